"""Fleet re-identification of archived history on Dask (issue 26)."""
