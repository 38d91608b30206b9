"""Plain helpers the tests import as ``support.…`` (tests/ is on pytest's pythonpath)."""
