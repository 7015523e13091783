"""A scenario's URDF robot, loaded once per process: the scenario's ``urdf:`` settings
(plan.description_spec.UrdfSpec) as :class:`UrdfOptions`, the load cached by file and
settings (every node of a process reads the same robot; descriptions.readers' URDF
reader)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from descriptions.urdf import LoadedUrdf, UrdfOptions, load_urdf
from plan.description_spec import UrdfSpec


def urdf_options(spec: UrdfSpec | None, scenario_dir: Path) -> UrdfOptions:
    """UrdfOptions from a scenario's ``urdf:`` settings; package folders are relative to
    the scenario's directory."""
    spec = spec or UrdfSpec()
    return UrdfOptions(
        args={k: str(v).lower() if isinstance(v, bool) else str(v)
              for k, v in spec.args.items()},
        packages={k: str((scenario_dir / v).resolve()) for k, v in spec.packages.items()},
        base=spec.base, wheels=spec.wheels, wheel_radius=spec.wheel_radius,
        wheel_separation=spec.wheel_separation, sensors=dict(spec.sensors),
        interfaces=dict(spec.interfaces),
        gains={k: {g: v for g, v in (("kp", s.kp), ("kv", s.kv)) if v is not None}
               for k, s in spec.gains.items()})


def section_options(section: dict | None, scenario_dir: Path) -> UrdfOptions:
    """UrdfOptions from a scenario's ``robots.urdf`` section as read from its YAML."""
    return urdf_options(UrdfSpec.model_validate(section or {}), scenario_dir)


def load_robot(path: Path | str, options: UrdfOptions) -> LoadedUrdf:
    """``load_urdf`` cached per process by the file and the options."""
    key = json.dumps({k: v for k, v in options.__dict__.items() if k != "env"},
                     sort_keys=True, default=list)
    return _cached(str(Path(path).resolve()), key, options)


_CACHE: dict[tuple[str, str, int, int], LoadedUrdf] = {}


def _cached(path: str, key: str, options: UrdfOptions) -> LoadedUrdf:
    stat = Path(path).stat()  # an edited file is read again (a notebook, the run API)
    full = (path, key, stat.st_mtime_ns, stat.st_size)
    if full not in _CACHE:
        _CACHE[full] = load_urdf(path, options)
    return _CACHE[full]


def layout_settings(spec: UrdfSpec | None, scenario_dir: Path) -> str:
    """A scenario's ``urdf:`` settings as the swarm layout carries them: JSON, the package
    folders made absolute (every process reads the same robot wherever it runs from)."""
    spec = spec or UrdfSpec()
    packages = {k: str((scenario_dir / v).resolve()) for k, v in spec.packages.items()}
    return spec.model_copy(update={"packages": packages}).model_dump_json()


def layout_urdf_robot(description: Path | str, settings: str) -> LoadedUrdf:
    """The robot of a swarm layout whose description is a URDF or xacro (``settings``:
    ``layout_settings``'s JSON), loaded once per process (descriptions.readers), keyed by
    the JSON itself: the settings become UrdfOptions only when the file is read, and its
    robot model carries them (``RobotModel.settings``)."""
    path = Path(description).resolve()
    stat = path.stat()  # an edited file is read again (a notebook, the run API)
    key = (str(path), settings, stat.st_mtime_ns, stat.st_size)
    if key not in _LAYOUT_CACHE:
        spec = UrdfSpec.model_validate_json(settings) if settings else UrdfSpec()
        loaded = load_urdf(path, urdf_options(spec, Path("/")))
        _LAYOUT_CACHE[key] = replace(loaded, model=replace(loaded.model, settings=settings))
    return _LAYOUT_CACHE[key]


_LAYOUT_CACHE: dict[tuple[str, str, int, int], LoadedUrdf] = {}
