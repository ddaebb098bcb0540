"""``python -m kgn_bench.cli``: the ``kgn-bench`` command."""

import sys

from .app import main

sys.exit(main())
