"""Task and plan files shipped with kgn_bench (``kgn_bench.config.resolve_task``)."""
