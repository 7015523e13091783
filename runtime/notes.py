"""Notes: what a node tells people about its work (why it stands still, what it could not
do), outside its outputs and the digest.

A step node calls ``self.note(text)`` (``nodes.contract``); after each step the driver takes
the notes with the step's tick. The lockstep runtime writes each one to the node's log and
appends it to ``logs/<node>.notes.jsonl`` as it comes (a crash keeps it); the in-process
driver keeps them in its result. The orchestrator puts them in orchestrator.log, the
manifest (``notes``) and the summary.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Note:
    """One note: which node, at which tick and time, and what it says."""

    node: str
    tick: int
    time_ns: int
    text: str

    def as_dict(self) -> dict:
        """JSON-ready, for the manifest and the notes file."""
        return {"node": self.node, "tick": self.tick, "time_s": self.time_ns / 1e9,
                "text": self.text}

    @classmethod
    def from_dict(cls, entry: dict) -> Note:
        """The note ``as_dict`` wrote."""
        return cls(str(entry["node"]), int(entry["tick"]), round(float(entry["time_s"]) * 1e9),
                   str(entry["text"]))

    def line(self) -> str:
        """'control at tick 0 (0.000 s): ...' for logs."""
        return f"{self.node} at tick {self.tick} ({self.time_ns / 1e9:.3f} s): {self.text}"


class NoteWriter:
    """Appends notes to a node's notes file, one JSON object a line, flushed at once."""

    def __init__(self, path: Path):
        self.path = path
        self.file = None

    def write(self, note: Note) -> None:
        """Append one note."""
        if self.file is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.file = open(self.path, "a")  # noqa: SIM115 - kept open for the run
        self.file.write(json.dumps(note.as_dict()) + "\n")
        self.file.flush()

    def truncate(self) -> None:
        """Forget the notes written so far (the run was reset to tick 0)."""
        if self.file is not None:
            self.file.seek(0)
            self.file.truncate()

    def close(self) -> None:
        """Close the file."""
        if self.file is not None:
            self.file.close()
            self.file = None


def read_notes(path: Path) -> list[Note]:
    """The notes of a notes file ([] when there is none; a torn last line is skipped)."""
    try:
        lines = path.read_text().splitlines()
    except OSError:
        return []
    notes = []
    for line in lines:
        try:
            notes.append(Note.from_dict(json.loads(line)))
        except (ValueError, KeyError, TypeError):
            continue
    return notes
