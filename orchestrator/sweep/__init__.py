"""cosim-sweep: many isolated runs of one scenario over seeds and parameter values.

- ``plan``: the product of seeds and values, each a ``RunSpec`` with a stable id.
- ``one_run``: what one run does, wherever it runs (a local worker or a Ray task).
- ``local_pool``: the embedded backend, worker processes on this machine.
- ``ray_backend``: each run a Ray task on any Ray cluster.
- ``results``: per-run records on disk (for ``--resume``), the table (CSV and Parquet).
- ``summary_picture``: success rate and metric distributions per parameter value.
- ``progress``: the progress bar with its ETA.
- ``cli``: the ``cosim-sweep`` command.
"""
