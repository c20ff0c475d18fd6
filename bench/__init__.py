"""Measurements, not shipped in the extension: ``runner`` (``python -m vpl_addon bench``: every method and Cycles
swept over their budgets, judged against converged references) and the scripts beside it, each run as
``.venv/bin/python bench/<script>.py`` (see README.md). May import everything else in the repository."""
