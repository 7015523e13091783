"""Rendered images compared with a tolerance: the lowest PSNR between two runs' frames.

Camera pixels differ between renderers (GPU EGL, Mesa llvmpipe, their versions) by a few
levels here and there; a PSNR floor (``--rendered-psnr DB``) accepts that and still catches
a camera that looks at the wrong thing. Frames are paired by tick; a frame only one run has
fails the floor. The peak is 255 for 8-bit images and, for float images (depth in metres),
the largest finite value of the reference frame.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plan.run_paths import RunPaths
from plan.timeutil import parse_tick_ns, tick_at_ns

_UINT8 = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1}
_FLOAT32 = {"32FC1": 1}
_UINT16 = {"16UC1": 1, "mono16": 1}


@dataclass(frozen=True)
class TopicPsnr:
    """The worst frame of one rendered topic: its tick and PSNR (inf: identical; None: the
    frame is missing in one run or its size or encoding differs)."""

    topic: str
    tick: int | None
    psnr: float | None
    frames: int = 0

    def describe(self) -> str:
        """'/camera/color/image_raw: lowest 38.2 dB at tick 25 (12 frames)'."""
        if self.tick is None:
            return f"{self.topic}: no frames"
        if self.psnr is None:
            return (f"{self.topic}: the frames at tick {self.tick} cannot be paired (one run "
                    "has none, or their size or encoding differs)")
        if math.isinf(self.psnr):
            return f"{self.topic}: {self.frames} frames, all identical"
        return f"{self.topic}: lowest {self.psnr:.1f} dB at tick {self.tick} ({self.frames} frames)"

    def passes(self, floor: float) -> bool:
        """Whether every frame pair is at or above ``floor`` dB."""
        return self.tick is None or (self.psnr is not None and self.psnr >= floor)


def image_array(msg) -> tuple[np.ndarray, float]:
    """The pixels of a sensor_msgs/Image as float64 (height, width, channels) and its peak."""
    enc = msg.encoding
    data = bytes(msg.data)
    if enc in _UINT8:
        dtype, channels, peak = np.uint8, _UINT8[enc], 255.0
    elif enc in _UINT16:
        dtype, channels, peak = np.dtype(">u2" if msg.is_bigendian else "<u2"), 1, 65535.0
    elif enc in _FLOAT32:
        dtype, channels, peak = np.dtype(">f4" if msg.is_bigendian else "<f4"), 1, 0.0
    else:
        raise ValueError(f"image encoding {enc!r} cannot be compared with a PSNR floor")
    row = np.frombuffer(data, dtype=np.uint8).reshape(msg.height, msg.step)
    width_bytes = msg.width * channels * np.dtype(dtype).itemsize
    pixels = row[:, :width_bytes].copy().view(dtype).reshape(msg.height, msg.width, channels)
    return pixels.astype(np.float64), peak


def psnr(reference, actual) -> float | None:
    """PSNR in dB of ``actual`` against ``reference`` (sensor_msgs/Image each): inf when
    equal, None when they cannot be paired (size or encoding)."""
    if (reference.encoding, reference.width, reference.height) != (
            actual.encoding, actual.width, actual.height):
        return None
    ref, peak = image_array(reference)
    act, _ = image_array(actual)
    finite = np.isfinite(ref) & np.isfinite(act)
    if not peak:
        peak = float(np.abs(ref[finite]).max()) if finite.any() else 1.0
    diff = np.subtract(ref, act, out=np.zeros_like(ref), where=finite)
    diff[np.isfinite(ref) != np.isfinite(act)] = peak  # a hole on one side only
    mse = float(np.mean(diff * diff))
    if mse == 0.0:
        return math.inf
    return 10.0 * math.log10(peak * peak / mse)


def lowest_psnr(reference_dir: Path, run_dir: Path, topics: list[str]) -> list[TopicPsnr]:
    """Per rendered topic, the worst frame pair of two run directories (paired by tick)."""
    out = []
    for topic in topics:
        ref, act = _frames(reference_dir, topic), _frames(run_dir, topic)
        worst: tuple[int | None, float | None] = (None, math.inf)
        ticks = sorted(set(ref) | set(act))
        for tick in ticks:
            value = psnr(ref[tick], act[tick]) if tick in ref and tick in act else None
            if worst[0] is None or value is None or value < worst[1]:
                worst = (tick, value)
            if value is None:
                break
        out.append(TopicPsnr(topic, worst[0], worst[1], len(ticks)))
    return out


def _frames(run_dir: Path, topic: str) -> dict[int, object]:
    """{tick: Image} of a topic in a run directory's bag (the last frame of a tick)."""
    from orchestrator.outputs.bag import BagReader

    manifest = json.loads(RunPaths(Path(run_dir)).manifest.read_text())
    bag = Path(run_dir) / (manifest.get("outputs", {}).get("bag") or "bag")
    tick_ns = parse_tick_ns(manifest["tick_ns"])
    with BagReader(bag) as reader:
        if topic not in reader.counts:
            return {}
        return {tick_at_ns(stamp, tick_ns): msg for stamp, msg in reader.messages(topic)}
