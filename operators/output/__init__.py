"""What writes files: a frame's EXR, baked sequences (here and on Dask farms), Cycles references."""
