"""The two ways a run can fail, after mosaik: before anything starts, or during the run."""


class ScenarioError(Exception):
    """The scenario is invalid; raised before any process starts (CLI exit code 2).

    The message is one paragraph naming the file, the key path and what would be accepted.
    """

    def __init__(self, file: str, key: str, problem: str, accepted: str = ""):
        self.file = str(file)
        self.key = key
        self.problem = problem
        self.accepted = accepted
        text = f"{self.file}: {key}: {problem}" if key else f"{self.file}: {problem}"
        if accepted:
            text += f" Accepted: {accepted}"
        super().__init__(text)


class SimulationError(Exception):
    """A run failed after it started (CLI exit code 3): names the node and what went wrong."""

    def __init__(self, message: str, node: str | None = None, tick: int | None = None):
        self.node = node
        self.tick = tick
        super().__init__(message)


class ScenarioWarning(UserWarning):
    """Something in a scenario that runs but deserves a word (e.g. an output nobody reads)."""
