"""Writes that fail (a full disk, a quota, a file-size limit): which file, on which file
system, how full it is; and the run's reserve of space for its last words (the manifest)."""

from __future__ import annotations

import os
from pathlib import Path

RESERVE_NAME = ".space-reserve"  # in the run directory, freed to write the manifest
RESERVE_BYTES = 512 * 1024


class WriteFailed(RuntimeError):
    """A write of the run's outputs failed; names the file and its file system. ``tick``:
    the tick whose records it was writing (-1: none in particular)."""

    def __init__(self, path: Path | str, exc: OSError, tick: int = -1):
        self.path = Path(path)
        self.errno = exc.errno
        self.tick = tick
        self.file_system = file_system(self.path)
        why = exc.strerror or str(exc)
        super().__init__(f"could not write {self.path} on {self.file_system}: {why} "
                         f"[errno {exc.errno}]")


def _unescape(text: str) -> str:
    return text.replace("\\040", " ").replace("\\011", "\t").replace("\\134", "\\")


def mount_of(path: Path) -> tuple[str, str]:
    """(mount point, file system type) of the mount that holds ``path`` (Linux; else '/', '?')."""
    target = str(Path(os.path.abspath(path)))
    best = ("/", "?")
    try:
        with open("/proc/self/mountinfo") as table:
            for line in table:
                fields = line.split()
                point = _unescape(fields[4])
                kind = fields[fields.index("-") + 1]
                inside = target == point or target.startswith(point.rstrip("/") + "/")
                if inside and len(point) >= len(best[0]):
                    best = (point, kind)
    except (OSError, ValueError, IndexError):
        pass
    return best


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} TiB"


def file_system(path: Path) -> str:
    """'the tmpfs file system at /mnt/small (4.0 MiB, 0 B free)'."""
    point, kind = mount_of(path)
    try:
        st = os.statvfs(point)
        room = f" ({_size(st.f_blocks * st.f_frsize)}, {_size(st.f_bavail * st.f_frsize)} free)"
    except OSError:
        room = ""
    return f"the {kind} file system at {point}{room}"


def reserve(run_dir: Path) -> None:
    """Set space aside in the run directory for its manifest (``release`` gives it back
    when a full disk would leave the run without one); nothing when there is no room."""
    try:
        with open(run_dir / RESERVE_NAME, "wb") as block:  # the blocks are taken at write
            block.write(b"\0" * RESERVE_BYTES)
    except OSError:
        release(run_dir)


def release(run_dir: Path) -> None:
    """Give the reserve back (done whatever happened, at the end of the run)."""
    try:
        (run_dir / RESERVE_NAME).unlink()
    except OSError:
        pass


def write_atomically(path: Path, text: str, run_dir: Path | None = None) -> None:
    """Write ``path`` whole or not at all (a temporary file renamed over it); on a full disk
    release ``run_dir``'s reserve and try once more. WriteFailed when it cannot."""
    temporary = path.with_name(f".{path.name}.tmp")
    for attempt in (1, 2):
        try:
            with open(temporary, "w") as out:
                out.write(text)
            os.replace(temporary, path)
            return
        except OSError as exc:
            try:
                temporary.unlink()
            except OSError:
                pass
            if attempt == 2 or run_dir is None:
                raise WriteFailed(path, exc) from exc
            release(run_dir)
