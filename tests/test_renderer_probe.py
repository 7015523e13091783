"""The manifest's renderer: probed once per GL set-up and user, not at every run with a
camera (orchestrator.outputs.renderer)."""

from __future__ import annotations

import pytest

from orchestrator.outputs import renderer


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """An empty cache of the user's and of this process's."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(renderer, "_answers", {})
    return tmp_path / "cosim" / "renderers"


def test_a_second_run_takes_the_answer_from_the_cache(fresh_cache, monkeypatch):
    first = renderer.RendererProbe()
    assert first._proc is not None  # nothing kept yet: a real probe
    answer = first.result()
    assert answer.startswith("egl: ") and "unknown" not in answer
    assert [p.read_text() for p in fresh_cache.iterdir()] == [answer]
    monkeypatch.setattr(renderer, "_answers", {})  # another process: the file answers
    second = renderer.RendererProbe()
    assert second._proc is None and second.result() == answer


def test_another_gl_set_up_probes_again(fresh_cache, monkeypatch):
    renderer.keep_answer(renderer.renderer_key({"MUJOCO_GL": "egl"}), "egl: kept")
    key = renderer.renderer_key({"MUJOCO_GL": "egl"})
    assert renderer.cached_answer(key) == "egl: kept"
    assert renderer.renderer_key({"MUJOCO_GL": "egl", "MESA_GL_VERSION_OVERRIDE": "3.3"}) != key
    assert renderer.renderer_key({"MUJOCO_GL": "osmesa"}) != key
    assert renderer.renderer_key({"MUJOCO_GL": "egl", "DRI_PRIME": "1"}) != key
    monkeypatch.setattr(renderer, "this_boot", lambda: "another host or boot")
    assert renderer.renderer_key({"MUJOCO_GL": "egl"}) != key
    monkeypatch.undo()
    monkeypatch.setenv("XDG_CACHE_HOME", str(fresh_cache.parent.parent))
    monkeypatch.setattr(renderer, "_answers", {})
    assert renderer.renderer_key({"MUJOCO_GL": "egl"}) == key
    assert renderer.renderer_key({"MUJOCO_GL": "egl", "HOME": "/elsewhere"}) == key
    libraries = renderer.gl_libraries()
    assert libraries and any(name.startswith("libEGL") for name, *_ in libraries)
    name, path, size, mtime = libraries[0]
    upgraded = [(name, path, size, mtime + 1), *libraries[1:]]  # Mesa upgraded in place
    monkeypatch.setattr(renderer, "gl_libraries", lambda: upgraded)
    assert renderer.renderer_key({"MUJOCO_GL": "egl"}) != key
    monkeypatch.setattr(renderer, "gl_libraries", lambda: None)  # no ldconfig: no cache
    assert renderer.renderer_key({"MUJOCO_GL": "egl"}) is None
    probe = renderer.RendererProbe()
    assert probe._proc is not None
    probe.result()
