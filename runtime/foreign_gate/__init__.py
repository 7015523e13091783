"""cosim's gate for foreign Python (rclpy) programs: put this directory first on a
program's PYTHONPATH with ``COSIM_GATE`` set, and its ``sitecustomize`` makes the program's
executor take each tick's fed inputs as one whole (see ``cosim_gate``)."""
