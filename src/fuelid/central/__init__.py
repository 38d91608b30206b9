"""The central PostgreSQL store every loop's service sends to (issue 26)."""
