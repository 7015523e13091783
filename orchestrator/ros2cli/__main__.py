"""``python -m orchestrator.ros2cli``: the same as the cosim-ros2 command."""

import sys

from orchestrator.ros2cli.cli import main

sys.exit(main())
