"""``python -m hysbench.benchmarks.cli``: the ``hysbench`` command."""

import sys

from hysbench.benchmarks.cli import main

sys.exit(main())
