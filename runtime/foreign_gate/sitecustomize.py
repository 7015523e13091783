"""Inject the cosim lockstep gate into a foreign rclpy program.

Put this directory first on ``PYTHONPATH`` and set ``COSIM_GATE`` (JSON, see
:mod:`cosim_gate`).  Without ``COSIM_GATE`` this file does nothing.  rclpy is
not imported here: the gate patches ``rclpy.executors`` and
``rclpy.time_source`` right after the program imports them.
"""

import os
import sys

if os.environ.get('COSIM_GATE'):
    try:
        import cosim_gate
        cosim_gate.install_from_env()
    except Exception as exc:  # a silently ungated program would be non-deterministic
        print(f'cosim gate: fatal: cannot install gate: {exc!r}', file=sys.stderr, flush=True)
        os._exit(78)
