"""The ``tourbot`` command line: parsing only; the work is done by the parts it calls.

Each module here named after a part defines ``register(app)`` adding that part's commands; the
benchmarks in :mod:`tourbot.bench` register under ``tourbot bench``. Heavy imports stay inside the
command functions so that ``tourbot --help`` is instant.
"""
