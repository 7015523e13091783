"""What the generated CDR encoder and decoder share: the primitive codes, the struct formats
of runs of fixed-size fields, and a writer of Python source compiled into a function."""

from __future__ import annotations

import importlib
import struct
from typing import Any

from rosidl_parser import definition as d

# struct codes of the primitive types both generators handle (char and wchar: rclpy's way)
CODES = {"boolean": "?", "octet": "c", "uint8": "B", "int8": "b", "int16": "h",
         "uint16": "H", "int32": "i", "uint32": "I", "float": "f", "int64": "q",
         "uint64": "Q", "double": "d"}


class Unsupported(Exception):
    """A field type a generator does not handle (the rclpy path handles it)."""


def code_of(slot: d.BasicType) -> str:
    """The struct code of a primitive field."""
    if slot.typename not in CODES:
        raise Unsupported(slot.typename)
    return CODES[slot.typename]


def size_of(slot: d.BasicType) -> int:
    """The size in bytes of a primitive field (its CDR alignment, up to 8)."""
    return struct.calcsize("<" + code_of(slot))


def class_of(slot: d.NamespacedType) -> type:
    """The message class a nested field names."""
    return getattr(importlib.import_module(".".join(slot.namespaces)), slot.name)


def run_format(run: list[tuple[int, str, str]], residue: int) -> str:
    """struct format of a run of fixed-size fields (align, code, expression) starting
    ``residue`` bytes past an 8-byte boundary: the alignment padding as ``x`` (zeros)."""
    pos, parts = residue, ["<"]
    for align, code, _ in run:
        pad = -pos % align
        if pad:
            parts.append(f"{pad}x")
        parts.append(code)
        pos += pad + struct.calcsize("<" + code)
    return "".join(parts)


class SourceWriter:
    """Indented lines of a function body, the constants it names, and fixed-size fields
    waiting to be packed or unpacked in one go (``run``)."""

    def __init__(self, consts: dict[str, Any]) -> None:
        self.lines: list[str] = []
        self.consts = dict(consts)
        self.run: list[tuple[int, str, str]] = []
        self.depth = 1
        self.names = 0

    def emit(self, line: str) -> None:
        """Append one line at the current indentation (an empty line is dropped)."""
        if line:
            self.lines.append("    " * self.depth + line)

    def const(self, value: Any) -> str:
        """A name under which the generated code sees ``value``."""
        name = f"K{len(self.consts)}"
        self.consts[name] = value
        return name

    def fresh(self, prefix: str) -> str:
        """A local variable name not used before."""
        self.names += 1
        return f"{prefix}{self.names}"

    placeholder = "0"  # what an empty struct's one placeholder byte is packed from/into

    def flush(self) -> None:
        """Write the code for the pending run of fixed-size fields."""
        raise NotImplementedError

    def message(self, msg_class: type, base: str) -> None:
        """The code for every field of ``msg_class``, the message being ``base``."""
        fields = list(msg_class.get_fields_and_field_types())
        if not msg_class.SLOT_TYPES:
            self.run.append((1, "B", self.placeholder))
        for name, slot in zip(fields, msg_class.SLOT_TYPES, strict=True):
            self.field(slot, f"{base}._{name}")

    def field(self, slot: Any, target: str) -> None:
        """The code for one field, by its type."""
        if isinstance(slot, d.BasicType):
            self.run.append((min(size_of(slot), 8), code_of(slot), target))
        elif isinstance(slot, d.AbstractWString):
            raise Unsupported("wstring")
        elif isinstance(slot, d.AbstractString):
            self.flush()
            self.string(target)
        elif isinstance(slot, d.NamespacedType):
            self.nested(class_of(slot), target)
        elif isinstance(slot, d.Array):
            self.flush()
            self.array(slot, target)
        elif isinstance(slot, d.AbstractSequence):
            self.flush()
            self.sequence(slot, target)
        else:
            raise Unsupported(repr(slot))

    def string(self, target: str) -> None:
        """The code for a string field (the run before it is flushed)."""
        raise NotImplementedError

    def nested(self, msg_class: type, target: str) -> None:
        """The code for a nested message field (its fixed-size fields join the run)."""
        raise NotImplementedError

    def array(self, slot: d.Array, target: str) -> None:
        """The code for a fixed-size array field (the run before it is flushed)."""
        raise NotImplementedError

    def sequence(self, slot: d.AbstractSequence, target: str) -> None:
        """The code for a sequence field (the run before it is flushed)."""
        raise NotImplementedError

    def run_formats(self) -> str:
        """The name of the 8 Structs of the pending run, one per alignment residue."""
        return self.const(tuple(struct.Struct(run_format(self.run, residue))
                                for residue in range(8)))

    def function(self, header: str, footer: str, name: str, what: str) -> Any:
        """Compile ``header``, the lines, ``footer`` into the function ``name``."""
        source = f"{header}\n" + "\n".join(self.lines) + f"\n{footer}\n"
        namespace = dict(self.consts)
        exec(compile(source, f"<cdr {what} of {name}>", "exec"), namespace)  # noqa: S102
        fn = namespace[name]
        fn.source = source
        return fn
