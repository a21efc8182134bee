"""Benchmarks: experiments that reproduce the papers' tables and compare tourbot with its peers.

Each module here defines ``register(bench_app)`` adding one ``tourbot bench NAME`` command, which
prints a table, writes a JSON file and records the command that produced it; ``docs/results.md``
holds the current figures.
"""
