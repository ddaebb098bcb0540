"""The Primitive Shape dataset: generation (``data.generate``) and the file format (``data.format``); the
training samples drawn from it live in ``kgn_bench.training.dataset``."""
