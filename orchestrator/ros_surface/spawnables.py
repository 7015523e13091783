"""GetSpawnables: what a client may spawn in this run, as the scenario's ``spawnables:``
list names it (``plan.spawnables.SpawnableSpec``: files, and folders of files), each as a
``file://`` URI SpawnEntity takes. A request's sources are served only where they are the
scenario's spawnables or inside their folders (``outside``); any other is named in the
result's message (``RESULT_NOT_FOUND``, whether it exists or not): a client on the graph
cannot make the run list or read the host's files. A folder lists the files the
description readers recognise (``descriptions.readers``) and the objects SpawnEntity reads
(``spawn_resources``: SDFormat, meshes) and MJCF files."""

from __future__ import annotations

from pathlib import Path

from descriptions.readers import reader_for
from orchestrator.ros_surface.spawn_resources import MESHES
from plan.scenario import Scenario
from plan.spawnables import SpawnableSpec

OTHERS = {"sdf": "SDFormat model", "xml": "MJCF",
          **{m.lstrip("."): f"mesh ({m.lstrip('.').upper()})" for m in MESHES}}


def _kind(file: Path) -> str | None:
    """What a file is for GetSpawnables, or None: not something cosim spawns from."""
    reader = reader_for(file)
    if reader.suffixes:
        return f"{reader.title} robot description"
    return OTHERS.get(file.suffix.lower().lstrip("."))


def spawnable_files(folder: Path, spawnables: list[SpawnableSpec]) -> list[tuple[Path, str]]:
    """(absolute file, description) of every spawnable: a file as given, a folder's files
    that cosim spawns from in name order; a description given by the entry wins."""
    out: list[tuple[Path, str]] = []
    for entry in spawnables:
        where = (folder / entry.path).resolve()
        if where.is_dir():
            out += [(f, entry.description or _kind(f)) for f in sorted(where.iterdir())
                    if f.is_file() and _kind(f) is not None]
        elif where.is_file():
            out.append((where, entry.description or _kind(where) or "a file"))
    return out


def outside(scenario: Scenario, source: str | Path) -> str | None:
    """Why a client may not name ``source`` (a path or ``file://`` URI), or None: it is
    one of the scenario's spawnables or inside one of their folders (after links are
    followed). The same answer whether it exists or not."""
    where = Path(str(source).removeprefix("file://")).expanduser().resolve()
    for entry in scenario.model.spawnables:
        allowed = (scenario.file.parent / entry.path).resolve()
        if where == allowed or (where.is_relative_to(allowed) and allowed.is_dir()):
            return None
    return (f"{str(source)!r} is not among this run's spawnables (clients name only the "
            f"scenario's spawnables: and what is in their folders); add it, or its folder, "
            f"to spawnables: in {scenario.file}.")


def list_spawnables(scenario: Scenario, sources: list[str] = ()
                    ) -> tuple[list[tuple[str, str]], list[str]]:
    """([(uri, description)], why each source not served was not): the scenario's
    spawnables, then each request source (a ``file://`` URI or a path) that is a file or
    folder inside them (``outside``)."""
    found = spawnable_files(scenario.file.parent, list(scenario.model.spawnables))
    unknown = []
    for source in sources:
        where = Path(source.removeprefix("file://")).expanduser()
        if (why := outside(scenario, source)) is not None:
            unknown.append(why)
        elif where.exists():
            found += spawnable_files(Path("/"), [SpawnableSpec(path=str(where.resolve()))])
        else:
            unknown.append(f"{source!r}: no such file or folder.")
    out, seen = [], set()
    for file, text in found:
        uri = f"file://{file}"
        if uri not in seen:
            seen.add(uri)
            out.append((uri, text))
    return out, unknown

