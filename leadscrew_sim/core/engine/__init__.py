"""The compiled engine: numba kernel, its stages and state layout. Read only through the model."""
