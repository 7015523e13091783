"""Turn a pydantic ValidationError into (key path, problem, what is accepted) for a user."""

from __future__ import annotations

import typing
from typing import Any

from pydantic import BaseModel, ValidationError


def key_path(loc: tuple, raw: Any) -> str:
    """('nodes', 1, 'rate') -> 'nodes[1] (sensors).rate', naming nodes where the data does."""
    out = ""
    node = raw
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
            node = node[part] if isinstance(node, list) and part < len(node) else None
            if isinstance(node, dict) and isinstance(node.get("name"), str):
                out += f" ({node['name']})"
        else:
            out += f".{part}" if out else str(part)
            node = node.get(part) if isinstance(node, dict) else None
    return out


def _model_at(model: type[BaseModel], loc: tuple) -> type[BaseModel] | None:
    """The pydantic model class that holds the last key of ``loc`` (for listing its fields)."""
    current: Any = model
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        info = current.model_fields.get(part)
        if info is None:
            return None
        current = _inner_model(info.annotation)
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def _inner_model(annotation: Any) -> Any:
    """The BaseModel inside list[...], X | None and friends."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _inner_model(arg)
        if found is not None:
            return found
    return None


def describe_validation_error(exc: ValidationError, raw: Any,
                              model: type[BaseModel] | None = None) -> tuple[str, str, str]:
    """The first error of ``exc`` as (key path, problem, accepted)."""
    if model is None:
        from orchestrator.model import ScenarioModel
        model = ScenarioModel
    err = exc.errors()[0]
    loc = tuple(err["loc"])
    key = key_path(loc, raw)
    more = f" ({exc.error_count() - 1} more error(s) after this one.)" if exc.error_count() > 1 else ""
    kind = err["type"]
    if kind == "extra_forbidden":
        owner = _model_at(model, loc)
        fields = ", ".join(owner.model_fields) if owner else "see the README"
        return key, f"unknown key {loc[-1]!r}.{more}", f"keys here are: {fields}."
    if kind == "missing":
        return key, f"required key is missing.{more}", _describe_field(model, loc)
    value = err.get("input")
    message = err["msg"].removeprefix("Value error, ")
    shown = repr(value) if not isinstance(value, (dict, list)) else type(value).__name__
    return key, f"{shown} is not valid: {message}.{more}", _describe_field(model, loc)


def _describe_field(model: type[BaseModel], loc: tuple) -> str:
    owner = _model_at(model, loc)
    name = loc[-1] if loc else None
    if owner is None or not isinstance(name, str) or name not in owner.model_fields:
        return "see the scenario reference in the README."
    info = owner.model_fields[name]
    hint = info.description or _annotation_text(info.annotation)
    return f"{name}: {hint}."


def _annotation_text(annotation: Any) -> str:
    return (getattr(annotation, "__name__", None) or str(annotation)).replace("typing.", "")
