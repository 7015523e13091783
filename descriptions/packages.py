"""ROS package lookup for robot descriptions: ``package://PKG/...`` URIs and xacro's
``$(find PKG)``, resolved as ROS resolves them.

Order: the scenario's ``packages:`` map (name -> the package's folder, the one holding its
``package.xml``), then every prefix of ``AMENT_PREFIX_PATH`` that registers the package in
its ament index (``share/ament_index/resource_index/packages/PKG``; the package's folder is
``PREFIX/share/PKG``), then ``ROS_PACKAGE_PATH`` (each entry a package or a tree searched
for a ``package.xml`` whose ``<name>`` is PKG, as rospack crawls).
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote

CRAWL_DEPTH = 4  # how deep a ROS_PACKAGE_PATH entry is searched for package.xml files


class PackageNotFound(LookupError):
    """A package that none of the places knows: its name and the places searched."""

    def __init__(self, package: str, searched: list[str]):
        self.package, self.searched = package, searched
        where = "; ".join(searched) if searched else "nothing to search"
        super().__init__(f"package {package!r} not found (searched: {where})")


@dataclass
class PackageResolver:
    """Finds ROS packages: the ``packages`` map first, then the two environment paths
    (taken from ``env``, os.environ when None)."""

    packages: Mapping[str, str | Path] = field(default_factory=dict)
    env: Mapping[str, str] | None = None
    _found: dict[str, Path] = field(default_factory=dict, repr=False)

    def find(self, package: str) -> Path:
        """The package's folder; PackageNotFound naming the places searched when unknown."""
        if package in self._found:
            return self._found[package]
        env = os.environ if self.env is None else self.env
        searched: list[str] = []
        if package in self.packages:
            path = Path(self.packages[package]).expanduser().resolve()
            if path.is_dir():
                return self._found.setdefault(package, path)
            searched.append(f"packages: {package}: {path} (not a folder)")
        else:
            searched.append("the packages: map")
        for prefix in _split(env.get("AMENT_PREFIX_PATH", "")):
            marker = Path(prefix, "share", "ament_index", "resource_index", "packages", package)
            if marker.exists():
                return self._found.setdefault(package, Path(prefix, "share", package).resolve())
        searched.append(f"AMENT_PREFIX_PATH={env.get('AMENT_PREFIX_PATH', '')!r}")
        for entry in _split(env.get("ROS_PACKAGE_PATH", "")):
            hit = _crawl(Path(entry), package, CRAWL_DEPTH)
            if hit is not None:
                return self._found.setdefault(package, hit.resolve())
        searched.append(f"ROS_PACKAGE_PATH={env.get('ROS_PACKAGE_PATH', '')!r}")
        raise PackageNotFound(package, searched)

    def resolve_uri(self, uri: str, base: Path) -> Path:
        """A mesh or file URI as a path: ``package://PKG/rel``, ``file:///abs`` or a path
        relative to ``base`` (the description's folder). PackageNotFound for an unknown
        package; the path is not checked for existence here."""
        if uri.startswith("package://"):
            rest = uri[len("package://"):]
            package, _, rel = rest.partition("/")
            return self.find(package) / unquote(rel)
        if uri.startswith("file://"):
            return Path(unquote(uri[len("file://"):]))
        path = Path(uri)
        return path if path.is_absolute() else base / path


def _split(value: str) -> list[str]:
    return [p for p in value.split(os.pathsep) if p]


def _package_name(folder: Path) -> str | None:
    try:
        name = ET.parse(folder / "package.xml").getroot().findtext("name")
    except (OSError, ET.ParseError):
        return None
    return re.sub(r"\s+", "", name) if name else None


def _crawl(root: Path, package: str, depth: int) -> Path | None:
    """The folder under ``root`` (itself included) whose package.xml names ``package``;
    a package's own subfolders are not searched (rospack stops at a package)."""
    if not root.is_dir():
        return None
    if (root / "package.xml").is_file():
        return root if _package_name(root) == package else None
    if depth == 0 or (root / "CATKIN_IGNORE").exists() or (root / "COLCON_IGNORE").exists():
        return None
    for child in sorted(root.iterdir()):
        if child.is_dir() and not child.name.startswith("."):
            hit = _crawl(child, package, depth - 1)
            if hit is not None:
                return hit
    return None
