"""The photon-map service: blocking for the offscreen host, in the background for the window."""

from __future__ import annotations

import threading
import time

import pytest

from app import indirect
from app.indirect import PhotonService
from app.photons import TracingCancelled
from app.scene import Scene
from app.settings import PhotonSettings


def _scene(name: str = "room") -> Scene:
    scene = Scene(name=name, meshes=[], materials=[], textures=[], lights=[])
    scene.indirect = True
    return scene


def _wait(predicate, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.005)


class _FakeTracer:
    """Stands in for ``indirect.trace``: reports progress, then waits to be released."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, int]] = []
        self.release = threading.Event()
        self.fail = False

    def __call__(self, settings, scene, progress=None, cancel=None):
        self.calls.append((settings.photons, settings.seed))
        if progress is not None:
            progress(0.5)
        while not self.release.wait(0.005):
            if cancel is not None and cancel():
                raise TracingCancelled("cancelled")
        if self.fail:
            raise RuntimeError("tracer bug")
        return f"map {settings.photons}/{settings.seed} of {scene.name}"


@pytest.fixture
def tracer(monkeypatch) -> _FakeTracer:
    fake = _FakeTracer()
    monkeypatch.setattr(indirect, "trace", fake)
    return fake


def test_blocking_ensure_traces_once_per_key(tracer):
    tracer.release.set()
    service, s, scene = PhotonService(), PhotonSettings(photons=64), _scene()
    assert service.ensure(s, scene) == "map 64/0 of room"
    assert service.ensure(s, scene) == "map 64/0 of room"
    s.radius_m = 0.5  # the radius does not change the traced photons
    assert service.ensure(s, scene) is not None and len(tracer.calls) == 1
    s.enabled = "off"
    assert service.ensure(s, scene) is None


def test_poll_traces_in_the_background_and_hands_the_map_over(tracer):
    service, s, scene = PhotonService(), PhotonSettings(photons=64), _scene()
    try:
        assert service.poll(s, scene) is None  # started, never blocks
        assert service.tracing
        _wait(lambda: service.progress == 0.5)
        assert service.poll(s, scene) is None
        tracer.release.set()
        _wait(lambda: service.poll(s, scene) is not None)
        assert not service.tracing and service.map == "map 64/0 of room"
        assert service.trace_ms > 0 and service.take_error() is None
        assert service.poll(s, scene) == "map 64/0 of room" and len(tracer.calls) == 1
    finally:
        service.close()


def test_poll_cancels_a_superseded_trace_and_starts_the_new_one(tracer):
    service, s, scene = PhotonService(), PhotonSettings(photons=64), _scene()
    try:
        service.poll(s, scene)
        _wait(lambda: len(tracer.calls) == 1)
        s.seed = 7  # the settings move on while tracing
        _wait(lambda: (service.poll(s, scene), len(tracer.calls) == 2)[1])
        assert service.map is None  # the cancelled trace stored nothing
        tracer.release.set()
        _wait(lambda: service.poll(s, scene) is not None)
        assert service.map == "map 64/7 of room"
        assert tracer.calls == [(64, 0), (64, 7)]
    finally:
        service.close()


def test_a_failed_trace_is_reported_once_and_not_retried(tracer, caplog):
    tracer.fail = True
    tracer.release.set()
    service, s, scene = PhotonService(), PhotonSettings(photons=64), _scene()
    try:
        service.poll(s, scene)
        _wait(lambda: (service.poll(s, scene), not service.tracing)[1])
        assert service.failed(s, scene)
        for record in caplog.records:  # logged with its traceback, as it should be
            record.expected = True
        assert service.take_error() == "room: tracer bug"
        assert service.take_error() is None
        assert service.poll(s, scene) is None and len(tracer.calls) == 1
    finally:
        service.close()
