"""The description reader registry (descriptions/readers.py): a file's format is recognised
there, and a new format is one reader and one registry entry: a run cannot tell a robot
read by a reader added in a test from the same robot read by the URDF reader."""

from __future__ import annotations

from dataclasses import replace

import pytest
import yaml

import nodes  # noqa: F401  (the node kinds, for loading scenarios)
from descriptions import readers
from descriptions.load import load_scenario
from descriptions.urdf_robot import layout_urdf_robot
from orchestrator.lockstep.inprocess import run_in_process
from tests.helpers import ROOT

BOT = ROOT / "scenarios" / "robots" / "mybot_description" / "urdf" / "mybot.urdf.xacro"


@pytest.mark.parametrize("path,reader", [
    ("robots/mybot.urdf.xacro", "urdf"), ("A/ROBOT.URDF", "urdf"), ("x.xacro", "urdf"),
    ("robot.usda", "usd"), ("robot.USDC", "usd"), ("robot.usd", "usd"),
    ("worlds/robot.xml", "mjcf"), ("robot.sdf", "mjcf"), ("robot.urdf.bak", "mjcf")])
def test_a_description_is_recognised_by_its_suffix_in_one_place(path, reader):
    assert readers.reader_for(path).name == reader
    assert readers.reader_for(path).described == (reader != "mjcf")
    assert readers.is_usd_file(path) == (reader == "usd")


def test_xacro_is_told_from_plain_urdf_and_mjcf_is_not_loaded_alone():
    assert readers.is_xacro_file("a/b.urdf.xacro") and not readers.is_xacro_file("a/b.urdf")
    assert readers.reader_named("") is readers.MJCF
    assert readers.robot_description_text("worlds/robot.xml", "") == ""
    with pytest.raises(ValueError, match="read from the world"):
        readers.load_robot("worlds/robot.xml", "")


def load_botx(description, settings):
    """The reader a test adds: mybot's xacro under another suffix, read as URDF is."""
    loaded = layout_urdf_robot(description, settings)
    return replace(loaded, model=replace(loaded.model, reader="botx"))


def _digest(scenario, tmp_path, description) -> str:
    doc = yaml.safe_load(scenario.read_text())
    doc["world"] = str((scenario.parent / doc["world"]).resolve())
    doc["robots"]["description"] = str(description)
    doc["robots"]["urdf"]["packages"] = {k: str((scenario.parent / v).resolve()) for k, v
                                         in doc["robots"]["urdf"]["packages"].items()}
    for node in doc["nodes"]:  # xacro's header comment names the file it expanded
        node.get("params", {}).pop("robot_description", None)
    path = tmp_path / f"{description.suffix[1:]}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return run_in_process(load_scenario(path, {"duration": "0.4s"})).digest


def test_a_new_format_is_one_reader_and_one_registry_entry(tmp_path, monkeypatch):
    botx = readers.Reader("botx", (".botx",), "urdf", "a botx", ".botx",
                          load="tests.test_readers:load_botx",
                          settings="descriptions.urdf_robot:layout_settings")
    monkeypatch.setattr(readers, "READERS", (botx, *readers.READERS))
    copy = tmp_path / "mybot.botx"
    copy.write_text(BOT.read_text())
    scenario = ROOT / "scenarios" / "nav_urdf.yaml"
    assert readers.reader_for(copy) is botx
    assert _digest(scenario, tmp_path, copy) == _digest(scenario, tmp_path, BOT)
