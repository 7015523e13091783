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
    unknown ``$(find PKG)``."""
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
    return _run_xacro(path, {k: str(v) for k, v in (args or {}).items()}, resolver)


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
    with _XACRO_LOCK, _find_patched(find), redirect_stderr(stderr):
        try:
            doc = xacro.process_file(str(path), mappings=dict(args))
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
    warnings = tuple(line for line in stderr.getvalue().splitlines() if line.strip())
    return Expanded(text, warnings)


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
