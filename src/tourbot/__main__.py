"""``python -m tourbot`` is the ``tourbot`` command."""

from tourbot.cli.main import main

main()
