"""Turn a pydantic ValidationError into (key path, problem, what is accepted) for a user."""

from __future__ import annotations

import re
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


def keys_of(model: type[BaseModel]) -> list[str]:
    """The keys a model accepts as a file spells them (a field's alias where it has one)."""
    return [info.alias or name for name, info in model.model_fields.items()]


def field_of(model: type[BaseModel], key: str):
    """The FieldInfo of the key ``key`` (a field name or alias), or None."""
    for name, info in model.model_fields.items():
        if key in (name, info.alias):
            return info
    return None


def _model_at(model: type[BaseModel], loc: tuple) -> type[BaseModel] | None:
    """The pydantic model class that holds the last key of ``loc`` (for listing its fields)."""
    current: Any = model
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        info = field_of(current, part)
        if info is None:
            return None
        current = inner_model(info.annotation)
    return current if isinstance(current, type) and issubclass(current, BaseModel) else None


def inner_model(annotation: Any) -> type[BaseModel] | None:
    """The BaseModel inside list[...], X | None and friends."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = inner_model(arg)
        if found is not None:
            return found
    return None


def describe_validation_error(exc: ValidationError, raw: Any,
                              model: type[BaseModel] | None = None) -> tuple[str, str, str]:
    """The first error of ``exc`` as (key path, problem, accepted)."""
    extra = exc.error_count() - 1
    more = f" ({extra} more error(s) after this one.)" if extra else ""
    return _describe(exc.errors()[0], raw, model, more)


def describe_validation_errors(exc: ValidationError, raw: Any,
                               model: type[BaseModel] | None = None
                               ) -> list[tuple[str, str, str]]:
    """Every error of ``exc`` as (key path, problem, accepted), in pydantic's order."""
    return [_describe(err, raw, model, "") for err in exc.errors()]


def unknown_keys(exc: ValidationError) -> list[tuple]:
    """The locations of the keys ``exc`` refuses as unknown (pydantic's extra_forbidden)."""
    return [tuple(err["loc"]) for err in exc.errors() if err["type"] == "extra_forbidden"]


def _describe(err: dict, raw: Any, model: type[BaseModel] | None, more: str
              ) -> tuple[str, str, str]:
    """One pydantic error as (key path, problem, accepted), ``more`` after the problem."""
    if model is None:
        from plan.model import ScenarioModel
        model = ScenarioModel
    loc = tuple(err["loc"])
    key = key_path(loc, raw)
    kind = err["type"]
    if kind == "extra_forbidden":
        owner = _model_at(model, loc)
        fields = ", ".join(keys_of(owner)) if owner else ""
        accepted = f"keys here are: {fields}." if fields else "no keys here."
        if owner is None:
            accepted = _reference(loc)
        return key, f"unknown key {loc[-1]!r}.{more}", accepted
    if kind == "missing":
        return key, f"required key is missing.{more}", _describe_field(model, loc)
    value = err.get("input")
    message = err["msg"].removeprefix("Value error, ")
    message = re.sub(r" or instance of \w+", "", message).replace("valid dictionary", "mapping")
    shown = repr(value) if not isinstance(value, (dict, list)) else type(value).__name__
    return key, f"{shown} is not valid: {message}.{more}", _describe_field(model, loc)


def _reference(loc: tuple) -> str:
    """Where a key the schema cannot describe here is explained: the documentation's page on
    it and the schema (plan/model.py, every key with its description)."""
    page = "how-to/remapping.md" if "remap" in loc else "reference/scenario.md"
    return (f"see docs/{page} and the schema in plan/model.py (every key described).")


def _describe_field(model: type[BaseModel], loc: tuple) -> str:
    """What the field at ``loc`` accepts: its description, or its type in words."""
    name, info, annotation = _field_at(model, loc)
    if name is None:
        return _reference(loc)
    hint = info.description if info is not None and info.description else None
    return f"{name}: {hint or describe_annotation(annotation)}."


def _field_at(model: type[BaseModel], loc: tuple) -> tuple[str | None, Any, Any]:
    """(name, FieldInfo or None, annotation) of the value at ``loc``, following lists and models."""
    current: Any = model
    name: str | None = None
    info: Any = None
    for part in loc:
        if isinstance(part, int):
            items = _list_item(current)
            if items is None:
                return None, None, None
            current, info, name = items, None, f"{name}[{part}]" if name else f"[{part}]"
            continue
        owner = inner_model(current)
        info = field_of(owner, part) if owner is not None else None
        if info is None:
            return None, None, None
        current, name = info.annotation, part
    return name, info, current


def _list_item(annotation: Any) -> Any:
    """The item type of list[X] (also inside X | None), or None."""
    if typing.get_origin(annotation) is list:
        return typing.get_args(annotation)[0]
    for arg in typing.get_args(annotation):
        if typing.get_origin(arg) is list:
            return typing.get_args(arg)[0]
    return None


def describe_annotation(annotation: Any) -> str:
    """A type annotation in words: 'a mapping with keys x, y', 'a list of ...', 'a number'."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return describe_annotation(args[0])
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return f"a mapping with keys {', '.join(keys_of(annotation))}"
    if origin is list:
        item = args[0] if args else None
        if isinstance(item, type) and issubclass(item, BaseModel):
            return f"a list of mappings, each with keys {', '.join(keys_of(item))}"
        return f"a list of {describe_annotation(item) if item else 'values'}"
    if origin is dict or annotation is dict:
        return "a mapping"
    if origin is typing.Literal:
        return "one of " + ", ".join(str(a) for a in args)
    if args and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return " or ".join(describe_annotation(a) for a in rest) + ", or leave it out"
    if args:
        return " or ".join(describe_annotation(a) for a in args)
    words = {bool: "true or false", int: "a whole number", float: "a number", str: "text"}
    return words.get(annotation, getattr(annotation, "__name__", str(annotation)))
