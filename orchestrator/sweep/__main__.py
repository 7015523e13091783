"""``python -m orchestrator.sweep`` is cosim-sweep."""

import sys

from orchestrator.sweep.cli import main

sys.exit(main())
