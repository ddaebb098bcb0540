"""Data shipped with kgn_bench: the arm MJCF and the trained weights (``kgn_bench.resources``)."""
