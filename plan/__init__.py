"""cosim's checked plan: the scenario model, its checks, the schedule, exact time, errors,
run options and run-directory paths. Below both the orchestrator and the node processes:
it imports neither."""
