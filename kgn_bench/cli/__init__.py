"""The ``kgn-bench`` command. Parses arguments and calls library functions; no logic of its own.

One module per group of commands (``data``, ``objects``, ``perf``, ``run`` and ``sweep``, ``benchmark`` with
``report``, ``export`` and ``check``, ``replay``, ``train`` and ``ship``, ``evaluation`` for ``eval``,
``studies`` for ``study`` and ``experiment``), each holding its parsers beside their handlers; ``options``
holds the shared parser pieces, ``common`` what the handlers share, ``app`` the top parser and ``main``.
Handlers import the library inside their bodies, so ``kgn-bench --help`` loads nothing heavy.

Errors a user can cause (``KGNBenchError``) print one line ``kgn-bench: error: ...`` and exit with status 2.
"""

from __future__ import annotations

from .app import build_parser, main

__all__ = ["build_parser", "main"]
