"""The applications built from the parts: the ready-wired simulated robot and the demo tour."""
