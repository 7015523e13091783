"""Build cosim's native pieces against the pip ROS 2 wheels (`make install` runs this).

- ``librmw_cosim_gate.so`` (runtime/rmw_gate/rmw_cosim_gate.c): the lockstep gate at the RMW
  layer. The functions that file defines are gated; every other rmw_* function the real
  middleware library exports (``nm -D`` of <venv>/lib/librmw_fastrtps_cpp.so) gets a generated
  x86-64 stub that jumps to the real one, resolved with dlopen at its first call. It installs
  into <venv>/cosim_native/lib, is linked as <venv>/lib/librmw_cosim_gate.so, and is put on the
  venv's ament index (packages/ and rmw_typesupport/ entries named rmw_cosim_gate), which is
  where a ROS install's rmw_implementation loader looks for ``RMW_IMPLEMENTATION=rmw_cosim_gate``.
  The pip wheels have no such loader (librcl links librmw_fastrtps_cpp.so directly), so there
  the library is preloaded (LD_PRELOAD) and its definitions take the place of the real ones.
- the C programs under tests/programs/*.c (plain rcl programs the tests run as foreign nodes),
  into <venv>/cosim_native/bin, with an rpath to the wheels' libraries and libpython (some
  generated libraries of the wheels reference Python symbols).

Everything is rebuilt only when an input changes (sources, compiler, wheel versions: hashed
into <venv>/cosim_native/.cosim_stamp). Run it with the venv's Python:
`.venv/bin/python tools/build_native.py [--force]`; a failure says what is missing and exits 1.
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import os
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
GATE_SOURCE = ROOT / "runtime" / "rmw_gate" / "rmw_cosim_gate.c"
PROGRAMS = ROOT / "tests" / "programs"
VENV = Path(sys.prefix)
OUT = VENV / "cosim_native"
STAMP = OUT / ".cosim_stamp"
RECIPE = "cosim-native-1"
GATE_NAME = "rmw_cosim_gate"
REAL_LIBRARY = "librmw_fastrtps_cpp.so"
MAX_STUBS = 1024  # the size of cosim_gate_real[] in the C file
# What the C programs link (the wheels' names).
PROGRAM_LIBS = ("rcl", "rcutils", "rmw", "rosidl_runtime_c", "std_msgs__rosidl_typesupport_c",
                "rosgraph_msgs__rosidl_typesupport_c")


class BuildError(Exception):
    """Something could not be built; the message says why and what to do."""


def gate_library() -> Path:
    """Where the gate library is linked into the venv (what LD_PRELOAD names)."""
    return VENV / "lib" / f"lib{GATE_NAME}.so"


def program_path(name: str) -> Path:
    """Where the C program tests/programs/<name>.c is installed."""
    return OUT / "bin" / name


def include_flags() -> list[str]:
    """One -I per package of the wheels' headers (<venv>/include/<pkg>/<pkg>/...)."""
    return [f"-I{d}" for d in sorted((VENV / "include").iterdir()) if d.is_dir()]


def wheel_lib_dirs() -> list[Path]:
    """<venv>/lib and the wheels' vendored library folders (site-packages/ros_*.libs)."""
    site = Path(sysconfig.get_paths()["purelib"])
    return [VENV / "lib", *sorted(p for p in site.glob("ros_*.libs") if p.is_dir())]


def run(cmd: list[str], what: str) -> str:
    """Run a build command; raise BuildError with its output if it fails."""
    try:
        done = subprocess.run(cmd, capture_output=True, text=True)
    except OSError as exc:
        raise BuildError(f"{what}: cannot run {cmd[0]} ({exc}); apt-get install gcc binutils"
                         ) from None
    if done.returncode != 0:
        raise BuildError(f"{what} failed (exit {done.returncode}):\n$ {' '.join(cmd)}\n"
                         f"{done.stdout}{done.stderr}")
    return done.stdout


def defined_rmw_functions(path: Path) -> list[str]:
    """The rmw_* functions an object or library defines (nm)."""
    out = run(["nm", "-D" if path.suffix == ".so" else "-g", "--defined-only", str(path)],
              f"listing the symbols of {path.name}")
    return sorted({m.group(1) for m in re.finditer(r"\sT\s(rmw_\w+)$", out, re.M)})


def stubs_source(names: list[str]) -> str:
    """x86-64 assembly: one forwarding stub per name, and the lazy first-call resolver."""
    lines = [".text", ".hidden cosim_gate_real", ".hidden cosim_gate_resolve"]
    for i, name in enumerate(names):
        lines += [".p2align 4", f".globl {name}", f".type {name}, @function", f"{name}:",
                  f"  movq cosim_gate_real+{8 * i}(%rip), %r11", "  testq %r11, %r11",
                  "  jz 1f", "  jmp *%r11", f"1: movq ${i}, %r11", "  jmp cosim_gate_lazy",
                  f".size {name}, .-{name}"]
    saves = [f"  movdqu %xmm{i}, {16 * i}(%rsp)" for i in range(8)]
    loads = [f"  movdqu {16 * i}(%rsp), %xmm{i}" for i in range(8)]
    regs = ["rdi", "rsi", "rdx", "rcx", "r8", "r9", "rax", "r11"]
    lines += [".p2align 4", "cosim_gate_lazy:",
              *[f"  pushq %{r}" for r in regs],
              "  subq $136, %rsp",  # 8 xmm registers, and the call's 16-byte alignment
              *saves, "  call cosim_gate_resolve", *loads, "  addq $136, %rsp",
              *[f"  popq %{r}" for r in reversed(regs)],
              "  leaq cosim_gate_real(%rip), %r10", "  movq (%r10,%r11,8), %r11",
              "  jmp *%r11", '.section .note.GNU-stack,"",@progbits', ""]
    return "\n".join(lines)


def names_source(names: list[str]) -> str:
    """C: the names the stubs forward, in stub order."""
    body = "".join(f'  "{n}",\n' for n in names)
    return ("#include <stddef.h>\n#define HIDDEN __attribute__((visibility(\"hidden\")))\n"
            f"HIDDEN const char * const cosim_gate_names[] = {{\n{body}  0}};\n"
            f"HIDDEN const size_t cosim_gate_name_count = {len(names)};\n")


def build_gate(work: Path) -> None:
    """Compile the gate, generate the forwarding of everything else, link, install."""
    real = VENV / "lib" / REAL_LIBRARY
    if not real.is_file():
        raise BuildError(f"{real} is missing: the ros-jazzy-rmw-fastrtps-cpp wheel "
                         "(a dependency of ros-jazzy-rclpy[fastrtps]); re-run `make install`")
    obj = work / "gate.o"
    run(["cc", "-c", "-O2", "-fPIC", "-Wall", "-Werror", *include_flags(), str(GATE_SOURCE),
         "-o", str(obj)], "compiling the RMW gate")
    gated = set(defined_rmw_functions(obj))
    forwarded = [n for n in defined_rmw_functions(real) if n not in gated]
    if len(forwarded) > MAX_STUBS:
        raise BuildError(f"{real.name} exports {len(forwarded)} functions; raise MAX_STUBS and "
                         "cosim_gate_real[] in rmw_cosim_gate.c")
    (work / "stubs.S").write_text(stubs_source(forwarded))
    (work / "names.c").write_text(names_source(forwarded))
    lib = OUT / "lib" / f"lib{GATE_NAME}.so"
    lib.parent.mkdir(parents=True, exist_ok=True)
    run(["cc", "-shared", "-O2", "-fPIC", f"-Wl,-soname,lib{GATE_NAME}.so", "-o", str(lib),
         str(obj), str(work / "stubs.S"), str(work / "names.c"), "-ldl", "-lpthread"],
        "linking the RMW gate")


def build_program(source: Path) -> None:
    """Compile one C program of tests/programs against rcl."""
    libdir = sysconfig.get_config_var("LIBDIR")
    ldlib = sysconfig.get_config_var("LDLIBRARY") or ""
    if not ldlib.endswith(".so") or not (Path(libdir) / ldlib).is_file():
        raise BuildError(f"this Python ({sys.executable}) has no shared libpython, which the "
                         "wheels' generated libraries need in a C program: a Python built with "
                         "--enable-shared")
    dirs = [*wheel_lib_dirs(), Path(libdir)]
    out = program_path(source.stem)
    out.parent.mkdir(parents=True, exist_ok=True)
    run(["cc", "-O2", "-Wall", "-Werror", *include_flags(), str(source), "-o", str(out),
         *[f"-L{d}" for d in dirs], *[f"-l{name}" for name in PROGRAM_LIBS],
         # the wheels need its symbols, not the program: keep it though nothing here uses it
         "-Wl,--no-as-needed", f"-l{ldlib[3:-3]}", "-Wl,--allow-shlib-undefined",
         "-Wl,--disable-new-dtags",
         "-Wl,-rpath," + ":".join(str(d) for d in dirs)], f"compiling {source.name}")


def register() -> None:
    """Link the gate into the venv prefix and put it on the ament index."""
    link = gate_library()
    target = OUT / "lib" / link.name
    if link.is_symlink() or not link.exists():
        link.unlink(missing_ok=True)
        link.symlink_to(os.path.relpath(target, link.parent))
    else:
        raise BuildError(f"{link} exists and is not ours; remove it")
    index = VENV / "share" / "ament_index" / "resource_index"
    (index / "packages").mkdir(parents=True, exist_ok=True)
    (index / "packages" / GATE_NAME).write_text("")
    fastrtps = index / "rmw_typesupport" / "rmw_fastrtps_cpp"
    typesupports = fastrtps.read_text() if fastrtps.is_file() else "rosidl_typesupport_c"
    (index / "rmw_typesupport").mkdir(parents=True, exist_ok=True)
    (index / "rmw_typesupport" / GATE_NAME).write_text(typesupports)


def input_hash() -> str:
    """The hash of everything that decides what is built."""
    digest = hashlib.sha256()
    for path in [GATE_SOURCE, Path(__file__), *sorted(PROGRAMS.glob("*.c"))]:
        digest.update(f"{path.relative_to(ROOT)}\0".encode() + path.read_bytes())
    real = VENV / "lib" / REAL_LIBRARY
    digest.update(real.read_bytes() if real.is_file() else b"")
    compiler = subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout
    digest.update(f"{RECIPE}\0{compiler}\0{sys.version}\0{platform.machine()}".encode())
    return digest.hexdigest()


def main(argv: list[str] | None = None) -> int:
    """Build what changed; 0 on success, 1 on failure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")
    args = parser.parse_args(argv)
    if sys.prefix == sys.base_prefix:
        print("build_native: run me with the venv's Python (.venv/bin/python)", file=sys.stderr)
        return 1
    if platform.machine() != "x86_64":
        print(f"build_native: the RMW gate's forwarding stubs are x86-64 only, not "
              f"{platform.machine()}: foreign programs that are not Python stay ungated",
              file=sys.stderr)
        return 0
    missing = [tool for tool in ("cc", "nm") if shutil.which(tool) is None]
    if missing:
        print(f"build_native: missing {', '.join(missing)} (apt-get install gcc binutils)",
              file=sys.stderr)
        return 1
    OUT.mkdir(exist_ok=True)
    with (OUT / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            wanted = input_hash()
            if args.force or not STAMP.is_file() or STAMP.read_text().strip() != wanted:
                with tempfile.TemporaryDirectory() as work:
                    build_gate(Path(work))
                for source in sorted(PROGRAMS.glob("*.c")):
                    build_program(source)
                STAMP.write_text(wanted + "\n")
                print(f"native: built lib{GATE_NAME}.so and "
                      f"{len(list(PROGRAMS.glob('*.c')))} C program(s)")
            register()
        except BuildError as exc:
            print(f"build_native: {exc}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
