"""Main job and honest evaluation of the identifiers (held-out data only)."""
