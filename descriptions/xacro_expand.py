"""A robot description's text: a ``.urdf`` read as it is, a xacro (``.xacro``,
``.urdf.xacro``) expanded with the ``xacro`` package from PyPI (the official ros/xacro; it
runs without ROS), its ``$(find PKG)`` resolved by cosim's :class:`PackageResolver`."""

from __future__ import annotations

import io
import threading
from collections.abc import Mapping
from contextlib import contextmanager, redirect_stderr
from dataclasses import dataclass
from pathlib import Path

from descriptions.description_error import DescriptionError
from descriptions.packages import PackageNotFound, PackageResolver

URDF_SUFFIXES = (".urdf", ".xacro")
_XACRO_LOCK = threading.Lock()  # xacro keeps its state in module globals


@dataclass(frozen=True)
class Expanded:
    """The expanded URDF text and what xacro said while expanding (its warnings)."""

    urdf: str
    warnings: tuple[str, ...] = ()
    declared: tuple[str, ...] = ()  # the <xacro:arg> names the description declares
    unused: frozenset[str] = frozenset()  # arguments given that it neither declares nor reads


def is_urdf(path: Path | str) -> bool:
    """True for a URDF or xacro description (by suffix: .urdf, .xacro, .urdf.xacro)."""
    return Path(path).suffix.lower() in URDF_SUFFIXES


def is_xacro(path: Path | str) -> bool:
    """True for a xacro description (.xacro, .urdf.xacro)."""
    return Path(path).suffix.lower() == ".xacro"


def expand(path: Path | str, args: Mapping[str, str] | None = None,
           resolver: PackageResolver | None = None) -> Expanded:
    """The URDF text of ``path``: xacro-expanded with ``args`` (``name:=value``) for a xacro
    (or a .urdf that declares the xacro namespace), read as it is for a plain .urdf.
    DescriptionError with xacro's own message on a xacro error, naming the package for an
    unknown ``$(find PKG)``, naming the arguments the description neither declares nor
    reads (xacro would ignore them: a misspelled name would run with the default)."""
    path = Path(path).resolve()
    resolver = resolver or PackageResolver()
    if not path.is_file():
        raise DescriptionError(str(path), "the file does not exist", path=str(path),
                               fix="give the path of a .urdf or .xacro file")
    text = path.read_text(encoding="utf-8")
    if not is_xacro(path) and not _declares_xacro(text):
        if args:
            raise DescriptionError(str(path), "xacro arguments given for a plain .urdf",
                                   fix="drop the arguments, or name the .xacro file")
        return Expanded(text)
    expanded = _run_xacro(path, {k: str(v) for k, v in (args or {}).items()}, resolver)
    if unused := [name for name in (args or {}) if name in expanded.unused]:
        declared = ", ".join(expanded.declared) or "none"
        several = len(unused) > 1
        raise DescriptionError(
            str(path), f"xacro argument{'s' if several else ''} "
            f"{', '.join(map(repr, unused))} {'are' if several else 'is'} not declared by "
            f"the description (xacro would ignore {'them' if several else 'it'} and use the "
            "defaults)", arg=unused[0], fix=f"the arguments it declares: {declared}")
    return expanded


def _declares_xacro(text: str) -> bool:
    """A .urdf that uses xacro (declares its namespace): many launch files run xacro on every
    description, so such a file is expanded too (TurtleBot3's .urdf files are xacro)."""
    return "http://www.ros.org/wiki/xacro" in text or "http://ros.org/wiki/xacro" in text


def _run_xacro(path: Path, args: dict[str, str], resolver: PackageResolver) -> Expanded:
    import xacro

    missing: list[PackageNotFound] = []

    def find(package: str) -> str:
        try:
            return str(resolver.find(package))
        except PackageNotFound as exc:
            missing.append(exc)
            raise

    stderr = io.StringIO()
    mappings = _WatchedArgs(args)
    with _XACRO_LOCK, _find_patched(find), redirect_stderr(stderr):
        try:
            doc = xacro.process_file(str(path), mappings=mappings)
        except Exception as exc:  # noqa: BLE001 - xacro raises many kinds; all are its errors
            if missing:
                raise DescriptionError(
                    str(path), f"$(find {missing[0].package}): {missing[0]}",
                    fix=f"add '{missing[0].package}: /path/to/{missing[0].package}' to the "
                        "robot's packages:, or source the workspace that has it") from None
            where = " > ".join(str(f) for f in reversed(xacro.filestack or []) if f)
            message = f"xacro error: {exc}" + (f" (in {where})" if where else "")
            raise DescriptionError(str(path), message,
                                   fix="correct the xacro; the message is xacro's own") from None
        text = doc.toxml()
    # xacro's banner names the file by its absolute path: the checkout's place would enter
    # /robot_description, and every digest with it (the same run gives one digest anywhere)
    text = text.replace(f"autogenerated by xacro from {path} ", f"autogenerated by xacro from "
                        f"{path.name} ", 1)
    warnings = tuple(line for line in stderr.getvalue().splitlines() if line.strip())
    return Expanded(text, warnings, tuple(mappings.declared), mappings.unused)


class _WatchedArgs(dict):
    """xacro's argument table, recording which names the description asks about: an
    ``<xacro:arg>`` asks whether it was given (``in``), a ``$(arg NAME)`` reads it. A
    given argument it never asks about is one xacro ignores."""

    def __init__(self, given: dict[str, str]):
        super().__init__(given)
        self.declared: dict[str, None] = {}  # in declaration order
        self.read: set[str] = set()

    def __contains__(self, name) -> bool:
        self.declared.setdefault(name, None)
        return super().__contains__(name)

    def __getitem__(self, name):
        self.read.add(name)
        return super().__getitem__(name)

    @property
    def unused(self) -> frozenset[str]:
        """The given arguments the description neither declared nor read."""
        return frozenset(self) - set(self.declared) - self.read


@contextmanager
def _find_patched(find):
    """xacro's ``$(find)`` and ``${find()}`` answered by ``find`` (xacro asks
    ament_index_python, which knows only AMENT_PREFIX_PATH)."""
    from xacro import substitution_args as sa

    saved_fn, saved_eval = sa._eval_find, sa._eval_dict["find"]
    sa._eval_find = sa._eval_dict["find"] = find
    try:
        yield
    finally:
        sa._eval_find, sa._eval_dict["find"] = saved_fn, saved_eval
