"""Identification: fit model parameters to recorded motion (cost, search, steps, bootstrap)."""
