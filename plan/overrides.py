"""Scenario overrides: given on a command line as KEY=VALUE (``--set``), applied to the
raw file before it is checked, and named in an error about a value they set."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from plan.errors import ScenarioError
from plan.validation import key_path


def parse_overrides(pairs: list[str]) -> dict:
    """['seed=3', 'nodes.a.rate=20'] -> {'seed': 3, 'nodes.a.rate': 20} (values are YAML)."""
    out = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ValueError(f"--set {pair!r}: expected KEY=VALUE")
        out[key] = yaml.safe_load(value)
    return out


def apply_override(raw: dict, key: str, value: Any, path: Path) -> tuple:
    """Set a dotted key ('seed', 'nodes.control.params.max_speed') in the raw scenario.

    A part that meets a list names a node (or is an index). Returns the key's location
    as a pydantic-style tuple, e.g. ('nodes', 1, 'rate').
    """
    parts = key.split(".") if isinstance(key, str) else [""]
    accepted = "a dotted key such as 'seed', 'duration' or 'nodes.<node name>.rate'."
    if not all(parts):
        raise ScenarioError(path, "", f"the override {key!r} is not a dotted key path.", accepted)
    target: Any = raw
    loc: list = []
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(target, list):
            index = _node_index(target, part)
            if index is None:
                names = [n["name"] for n in target if isinstance(n, dict) and "name" in n]
                raise ScenarioError(path, key, f"override names no node {part!r}.",
                                    f"a node name: {', '.join(map(str, names)) or 'none'}.")
            loc.append(index)
            if last:
                target[index] = copy.deepcopy(value)
            target = target[index]
            continue
        if not isinstance(target, dict):
            through = ".".join(parts[:i])
            raise ScenarioError(path, key, f"override goes through {through}, which is "
                                f"{type(target).__name__}, not a mapping.", accepted)
        loc.append(part)
        if last:
            target[part] = copy.deepcopy(value)
        else:
            target = target.setdefault(part, {})
    return tuple(loc)


def _node_index(nodes: list, part: str) -> int | None:
    """The index of the node named ``part`` (or given by its index) in a raw nodes list."""
    for i, node in enumerate(nodes):
        if isinstance(node, dict) and node.get("name") == part:
            return i
    if part.isdigit() and int(part) < len(nodes):
        return int(part)
    return None


def blame_override(exc: ScenarioError, raw: dict, overridden: dict[str, tuple],
                    overrides: dict[str, Any]) -> ScenarioError:
    """Add which override set the value to an error about an overridden key (to each of
    the problems of an error that names several)."""
    if len(exc.errors) > 1:
        return ScenarioError.every([blame_override(e, raw, overridden, overrides)
                                    for e in exc.errors])
    for key, loc in overridden.items():
        shown = key_path(loc, raw)
        if _within(exc.key, shown) or _within(shown, exc.key):
            return ScenarioError(exc.file, exc.key, f"{exc.problem} (The value comes from the "
                                 f"override {key}={overrides[key]!r}.)", exc.accepted)
    return exc


def _within(key: str, outer: str) -> bool:
    """Whether key path ``key`` is ``outer`` or inside it."""
    return bool(outer) and (key == outer or key.startswith((outer + ".", outer + "[")))
