"""GetSpawnables: what a client may spawn in this run, as the scenario's ``spawnables:``
list names it (``plan.events.SpawnableSpec``: files, and folders of files), each as a
``file://`` URI SpawnEntity takes; sources a request adds that are local files or folders
are listed the same way, others are named as unrecognised."""

from __future__ import annotations

from pathlib import Path

from plan.events import SpawnableSpec, spawnable_files
from plan.scenario import Scenario

KINDS = {".urdf": "URDF", ".xacro": "xacro (URDF)", ".usd": "USD", ".usda": "USD",
         ".usdc": "USD", ".xml": "MJCF", ".sdf": "SDFormat", ".stl": "mesh (STL)",
         ".obj": "mesh (OBJ)", ".dae": "mesh (COLLADA)"}


def list_spawnables(scenario: Scenario, sources: list[str] = ()
                    ) -> tuple[list[tuple[str, str]], list[str]]:
    """([(uri, description)], the sources not recognised): the scenario's spawnables, then
    each request source that is a local file or folder (a ``file://`` URI or a path)."""
    folder = scenario.file.parent
    found = spawnable_files(folder, list(scenario.model.spawnables))
    unknown = []
    for source in sources:
        where = Path(source.removeprefix("file://"))
        if where.exists():
            found += spawnable_files(Path("/"), [SpawnableSpec(path=str(where.resolve()))])
        else:
            unknown.append(source)
    out, seen = [], set()
    for file, text in found:
        uri = f"file://{file}"
        if uri not in seen:
            seen.add(uri)
            out.append((uri, text or KINDS.get(file.suffix.lower(), "a file")))
    return out, unknown
