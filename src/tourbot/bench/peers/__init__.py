"""Adapters to the peers tourbot is measured against (benchmark-only: ``pip install tourbot[peers]``)."""
