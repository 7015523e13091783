"""A scenario's URDF robot, loaded once per process: the scenario's ``urdf:`` settings
(plan.description_spec.UrdfSpec) become :class:`UrdfOptions` once, when the scenario loads,
carried by the layout as the options' JSON; the load is cached by file and that JSON (every
node of a process reads the same robot; descriptions.readers' URDF reader)."""

from __future__ import annotations

import json
from dataclasses import fields, replace
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
    """UrdfOptions from a scenario's ``robots.urdf`` section as read from its YAML
    (cosim-describe), by the run's way: the settings JSON its layout carries, read back."""
    return options_of(layout_settings(UrdfSpec.model_validate(section or {}), scenario_dir))


def layout_settings(spec: UrdfSpec | None, scenario_dir: Path) -> str:
    """A scenario's ``urdf:`` settings as the swarm layout carries them: the UrdfOptions
    they mean, as JSON (package folders absolute: every process reads the same robot
    wherever it runs from), so a process reading the robot makes the options straight from
    it (``options_of``)."""
    options = urdf_options(spec, scenario_dir)
    return json.dumps({f.name: getattr(options, f.name) for f in fields(options)
                       if f.name != "env"}, sort_keys=True)


def options_of(settings: str) -> UrdfOptions:
    """The UrdfOptions of a layout's settings JSON (``layout_settings``; '': defaults)."""
    given = json.loads(settings) if settings else {}
    if given.get("wheels") is not None:
        given["wheels"] = tuple(given["wheels"])
    return UrdfOptions(**given)


def layout_urdf_robot(description: Path | str, settings: str) -> LoadedUrdf:
    """The robot of a swarm layout whose description is a URDF or xacro (``settings``:
    ``layout_settings``'s JSON), loaded once per process (descriptions.readers), keyed by
    the JSON itself; its robot model carries them (``RobotModel.settings``)."""
    path = Path(description).resolve()
    stat = path.stat()  # an edited file is read again (a notebook, the run API)
    key = (str(path), settings, stat.st_mtime_ns, stat.st_size)
    if key not in _CACHE:
        loaded = load_urdf(path, options_of(settings))
        _CACHE[key] = replace(loaded, model=replace(loaded.model, settings=settings))
    return _CACHE[key]


_CACHE: dict[tuple[str, str, int, int], LoadedUrdf] = {}
