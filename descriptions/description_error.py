"""The one error a robot description (URDF, xacro or USD) raises when it cannot be loaded."""

from __future__ import annotations

from pathlib import Path

from plan.errors import ScenarioError


class DescriptionError(ValueError):
    """A description that cannot be loaded: the file, the link or joint (when one is to
    blame; a USD description's prim path, ``prim``), the xacro argument (``arg``: one the
    scenario gives), the path tried (a mesh, a package), what is wrong and the fix.
    The scenario layer turns it into a ScenarioError (exit 2) before anything starts."""

    def __init__(self, description: str, problem: str, *, link: str | None = None,
                 joint: str | None = None, path: str | None = None, fix: str = "",
                 arg: str | None = None, prim: str | None = None):
        self.description, self.problem, self.fix = str(description), problem, fix
        self.prim = prim
        self.link, self.joint, self.path, self.arg = link, joint, path, arg
        where = self.description
        if link:
            where += f", link {link!r}"
        if joint:
            where += f", joint {joint!r}"
        if prim:
            where += f", prim {prim}"
        text = f"robot description {where}: {problem}"
        if path:
            text += f" (tried {path})"
        if fix:
            text += f". Fix: {fix}"
        super().__init__(text)


def scenario_error(exc: DescriptionError, file: Path | str, key: str) -> ScenarioError:
    """The ScenarioError (exit 2) a DescriptionError is in scenario ``file`` at ``key``."""
    return ScenarioError(file, key, str(exc) + ("" if str(exc).endswith(".") else "."))
