"""The command line, ``python -m vpl_addon COMMAND``."""
