"""The robot description readers: one per format, behind one registry. Every place that
needs to know how a description is read asks here (``reader_for``), and only here is a
file's format recognised (by its suffix). Adding a format is one :class:`Reader` and one
entry in ``READERS``.

What a reader gives (``load_robot``) is one loaded robot (``descriptions.urdf.LoadedUrdf``
today, for every described format): the robot model (``descriptions.robot_model``: frames,
joints and their command interfaces, drive, sensors, as plain data), the MuJoCo fragment to
attach (an MjSpec with cosim's actuators and sensors), the URDF text /robot_description
carries and the notes on what the reading changed. An MJCF robot is the exception that
needs no reading: its MjSpec is the file, and its model is read out of the compiled world
by name (``descriptions.robot_reader``), so its reader's ``load`` is None.

A reader's ``settings`` is the JSON a swarm layout carries (``plan.robots.RobotsLayout``,
its ``urdf`` field): the scenario's ``robots.<settings_key>`` section as every process
reads it, package folders made absolute.

This module imports no reader at import time (USD's pulls in usd-core): each reader's
functions are named ``module:function`` and imported on first use.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import mujoco


def _function(name: str) -> Callable[..., Any]:
    module, function = name.split(":")
    return getattr(importlib.import_module(module), function)


@dataclass(frozen=True)
class Reader:
    """One description format: its name (``RobotModel.reader`` of the robots it makes), the
    suffixes that recognise its files (lower case; empty: the fallback), the ``robots:`` key
    holding its settings (None: it takes none), the words that name a description of it
    and its files in messages,
    and its functions as ``module:function``: ``load`` (description, settings JSON) ->
    LoadedUrdf, cached per process; ``settings`` (its pydantic section or None, the
    scenario's folder) -> settings JSON; for ``cosim-describe``, ``load_with`` (description,
    UrdfOptions) -> LoadedUrdf and ``options`` (its section as a dict or None, the
    scenario's folder) -> UrdfOptions. ``says_notes``: its losses are said once when the
    scenario loads (descriptions.robot_layout)."""

    name: str
    suffixes: tuple[str, ...]
    settings_key: str | None
    title: str
    files: str
    load: str | None = None
    settings: str | None = None
    load_with: str | None = None
    options: str | None = None
    says_notes: bool = False

    @property
    def described(self) -> bool:
        """Whether the reader makes the robot model itself (URDF, xacro, USD), its own names
        on /joint_states and TF; False for MJCF (the model is read from the world)."""
        return self.load is not None

    def recognises(self, path: Path | str) -> bool:
        """Whether ``path`` is a file of this format, by its suffix."""
        return str(path).lower().endswith(self.suffixes) if self.suffixes else False


URDF = Reader("urdf", (".urdf", ".xacro"), "urdf", "a URDF or xacro",
              ".urdf, .xacro or .urdf.xacro", load="descriptions.urdf_robot:layout_urdf_robot",
              settings="descriptions.urdf_robot:layout_settings",
              load_with="descriptions.urdf:load_urdf",
              options="descriptions.urdf_robot:section_options")
USD = Reader("usd", (".usd", ".usda", ".usdc"), "usd", "a USD", ".usd, .usda or .usdc",
             load="descriptions.usd_robot:layout_usd_robot",
             settings="descriptions.usd_robot:layout_settings",
             load_with="descriptions.usd_robot:load_usd",
             options="descriptions.usd_robot:section_options", says_notes=True)
MJCF = Reader("mjcf", (), None, "an MJCF", ".xml")
READERS: tuple[Reader, ...] = (URDF, USD, MJCF)  # the first that recognises a file; MJCF else


def reader_for(description: Path | str) -> Reader:
    """The reader of a robot description file (MJCF for any file no other recognises)."""
    return next((r for r in READERS if r.recognises(description)), MJCF)


def reader_named(name: str) -> Reader:
    """The reader named ``name`` (``RobotModel.reader``); MJCF for '' (a robot read from an
    MJCF world)."""
    return next((r for r in READERS if r.name == name), MJCF)


def is_usd_file(path: Path | str) -> bool:
    """Whether a file (a world or a robot) is OpenUSD, by its suffix."""
    return USD.recognises(path)


def is_xacro_file(path: Path | str) -> bool:
    """Whether a URDF reader's file is xacro (``.xacro``, ``.urdf.xacro``: expanded before
    it is read), by its suffix."""
    return str(path).lower().endswith(".xacro")


def load_robot(description: Path | str, settings: str):
    """The robot of a described format (``descriptions.urdf.LoadedUrdf``), read with the
    layout's ``settings`` JSON, once per process; a DescriptionError on anything wrong, a
    ValueError for a format that is not described (MJCF)."""
    reader = reader_for(description)
    if reader.load is None:
        raise ValueError(f"{description}: an {reader.name} robot is read from the world, "
                         "not loaded alone")
    loaded = _function(reader.load)(description, settings)
    if loaded.model.settings != settings:  # a reader whose model does not say it (cached
        # loads do: this copies at every call)
        loaded = replace(loaded, model=replace(loaded.model, settings=settings))
    return loaded


def layout_settings(description: Path | str, section: Any, scenario_dir: Path) -> str:
    """The settings JSON a layout carries for ``description`` from its reader's section of
    the scenario (None: not given); '' for a reader that takes none (MJCF)."""
    reader = reader_for(description)
    if reader.settings is None:
        return ""
    return _function(reader.settings)(section, scenario_dir)


def describing_reader(description: Path | str) -> Reader:
    """The reader ``cosim-describe`` reads ``description`` with: its own, or URDF's for a
    file no described format recognises (whose error says what it takes)."""
    reader = reader_for(description)
    return reader if reader.load_with is not None else URDF


def load_with_options(description: Path | str, options):
    """``description`` read with ``UrdfOptions`` (cosim-describe's command line) by its
    reader, uncached; a DescriptionError on anything wrong."""
    return _function(describing_reader(description).load_with)(description, options)


def section_options(description: Path | str, section: dict | None, scenario_dir: Path):
    """The UrdfOptions a scenario's ``robots.<settings_key>`` section (a dict, None: not
    given) means for ``description``'s reader."""
    return _function(describing_reader(description).options)(section, scenario_dir)


def robot_spec(description: Path | str, settings: str) -> mujoco.MjSpec:
    """The MuJoCo fragment of one robot, to attach into a world: a described robot's
    converted spec (cached per process), an MJCF's file as it is."""
    if reader_for(description).described:
        return load_robot(description, settings).spec
    return mujoco.MjSpec.from_file(str(description))


def robot_description_text(description: Path | str, settings: str) -> str:
    """What /robot_description carries for a described robot (its URDF, expanded or
    written from USD); '' for an MJCF robot. A robot model carries both arguments
    (``RobotModel.source``, ``RobotModel.settings``)."""
    if not reader_for(description).described:
        return ""
    return load_robot(description, settings).urdf_text
