"""Read a scenario file: read its YAML strictly, apply overrides, validate the schema, and
hand the model to ``plan.resolve`` for the semantic checks, its world files read through
the world loader given (``descriptions.load.load_scenario`` gives MuJoCo's and USD's).

Everything that can be wrong with a scenario is found before any process starts, and
reported as a ``ScenarioError`` naming the file, the key path and what is accepted.
"""

from __future__ import annotations

import copy
import hashlib
import sys
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from plan.errors import Problems, ScenarioError
from plan.model import ScenarioModel
from plan.overrides import apply_override, blame_override
from plan.resolve import resolve
from plan.scenario import Scenario
from plan.validation import describe_validation_errors, unknown_keys
from plan.world_reader import WorldReader


def read_scenario(path: str | Path, worlds: WorldReader,
                  overrides: dict[str, Any] | None = None) -> Scenario:
    """Read, check and resolve a scenario file, its world files read through ``worlds``;
    raise ScenarioError on anything wrong.

    ``overrides`` maps dotted keys ('seed', 'nodes.<node name>.rate') to values that replace
    the file's before anything is checked; an error in an overridden value says so.
    """
    path = Path(path)
    raw, text = _read_yaml(path)
    make_importable(path.parent, Path.cwd())
    overrides = dict(overrides or {})
    overridden = {key: apply_override(raw, key, value, path) for key, value in overrides.items()}
    found = Problems()
    try:
        model, schema_errors = _validate(path, raw)
        found.errors += schema_errors
        if model is not None:
            with found.collecting():
                scenario = resolve(path, model, hashlib.sha256(text).hexdigest(), overrides,
                                   worlds)
        found.raise_any()
        return scenario
    except ScenarioError as exc:
        raise blame_override(exc, raw, overridden, overrides) from None


def read_raw(path: str | Path, overrides: dict[str, Any] | None = None) -> dict:
    """The scenario file's YAML as written, with ``overrides`` applied, unchecked: what a
    front end adds to before loading it (its robots' urdf:/usd: settings and relative
    paths as the file has them). ScenarioError for a file that cannot be read."""
    path = Path(path)
    raw, _ = _read_yaml(path)
    for key, value in (overrides or {}).items():
        apply_override(raw, key, value, path)
    return raw


def _validate(path: Path, raw: dict) -> tuple[ScenarioModel | None, list[ScenarioError]]:
    """The schema's model of ``raw`` and every problem pydantic finds in it. When the only
    problems are unknown keys, the model is that of the file without them: a key the schema
    does not know changes nothing else, so the later checks still run and their problems
    are reported with it. None when the schema refuses more than that."""
    try:
        return ScenarioModel.model_validate(raw), []
    except ValidationError as exc:
        errors = [ScenarioError(path, *found) for found in describe_validation_errors(exc, raw)]
        unknown = unknown_keys(exc)
        if len(unknown) < exc.error_count():
            return None, errors
        try:
            return ScenarioModel.model_validate(_without(raw, unknown)), errors
        except (ValidationError, LookupError, TypeError):
            return None, errors


def _without(raw: dict, locations: list[tuple]) -> dict:
    """A copy of ``raw`` without the keys at ``locations`` (pydantic's locs; LookupError
    or TypeError for one that is not a path in the data, as a union member's tag)."""
    out = copy.deepcopy(raw)
    for loc in locations:
        target = out
        for part in loc[:-1]:
            target = target[part]
        del target[loc[-1]]
    return out


def make_importable(*folders: Path) -> None:
    """Let ``module: mypkg.mymod:MyNode`` load from the scenario's folder and the working
    directory, as pytest's rootdir does, in the orchestrator and in every node process (each
    loads the scenario): added after the installed packages, so they never shadow one."""
    for folder in folders:
        entry = str(folder.resolve())
        if entry not in sys.path:
            sys.path.append(entry)


# libyaml's safe loader when PyYAML was built with it (10x faster; every process of a run
# parses the scenario), the pure-Python one otherwise: same documents, same errors.
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_YAML_STR = "tag:yaml.org,2002:str"
_YAML_MERGE = "tag:yaml.org,2002:merge"


def _read_yaml(path: Path) -> tuple[dict, bytes]:
    # exists(), not is_file(): /dev/null or a pipe is read like a file (and may be empty)
    if not path.exists() or path.is_dir():
        what = "is a directory, not a file" if path.is_dir() else "does not exist"
        raise ScenarioError(path, "", f"the scenario file {what}.",
                            "the path of a YAML scenario file, e.g. scenarios/nav.yaml.")
    try:
        text = path.read_bytes()
    except OSError as exc:
        raise ScenarioError(path, "", f"the scenario file cannot be read: {exc.strerror}.",
                            "a readable YAML scenario file.") from None
    try:
        root = yaml.compose(text, Loader=_LOADER)
        if root is not None:
            _check_yaml_keys(root, "", path, set())
        raw = yaml.load(text, Loader=_LOADER)  # noqa: S506 - a safe loader
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ScenarioError(path, "", f"YAML syntax error{where}: {problem}.",
                            "valid YAML; check indentation and quoting there.") from None
    if raw is None:
        raise ScenarioError(path, "", "the file is empty.",
                            "a mapping with at least name, duration and nodes.")
    if not isinstance(raw, dict):
        raise ScenarioError(path, "", f"the top level is a {type(raw).__name__}, not a mapping.",
                            "a mapping with keys such as name, seed, duration, nodes.")
    return raw, text


def _check_yaml_keys(node: yaml.Node, where: str, path: Path, seen_nodes: set[int]) -> None:
    """Refuse what plain YAML loading would hide: repeated keys and keys that are not text."""
    if id(node) in seen_nodes:
        return
    seen_nodes.add(id(node))
    if isinstance(node, yaml.MappingNode):
        lines: dict[str, int] = {}
        for key_node, value_node in node.value:
            if key_node.tag == _YAML_MERGE:
                continue
            line = key_node.start_mark.line + 1
            shown = key_node.value if isinstance(key_node, yaml.ScalarNode) else "?"
            key = f"{where}.{shown}" if where else str(shown)
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag != _YAML_STR:
                raise ScenarioError(path, key, f"the key {shown!r} at line {line} is not text "
                                    f"(YAML reads it as {key_node.tag.rsplit(':', 1)[-1]}).",
                                    f"a text key; quote it, e.g. '{shown}':")
            if shown in lines:
                raise ScenarioError(path, key, f"the key {shown!r} appears twice, at lines "
                                    f"{lines[shown]} and {line}.", "each key once per mapping.")
            lines[shown] = line
            _check_yaml_keys(value_node, key, path, seen_nodes)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            label = f"{where}[{i}]"
            if isinstance(item, yaml.MappingNode):
                names = [v.value for k, v in item.value
                         if isinstance(k, yaml.ScalarNode) and k.value == "name"
                         and isinstance(v, yaml.ScalarNode) and v.tag == _YAML_STR]
                label += f" ({names[0]})" if names else ""
            _check_yaml_keys(item, label, path, seen_nodes)
