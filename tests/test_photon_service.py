"""The photon-map service: blocking for the offscreen host, in the background for the window;
the map grown while the viewer stands."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from app import indirect
from app.indirect import PhotonService
from app.irradiance_cache import cache_for
from app.photon_map import PhotonMap, merge
from app.photons import TracingCancelled, trace_photons
from app.scene import Scene
from app.settings import PhotonSettings
from tests.test_photon_render import box_room


def _scene(name: str = "room") -> Scene:
    scene = Scene(name=name, meshes=[], materials=[], textures=[], lights=[])
    scene.indirect = True
    return scene


def _wait(predicate, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.005)


class _Traced(str):
    """A fake map: its name, and the paths it was traced with."""

    emitted = 0


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
        traced = _Traced(f"map {settings.photons}/{settings.seed} of {scene.name}")
        traced.emitted = settings.photons
        return traced


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


# -- growing the map while the viewer stands (photons.refine_photons) ----------------------------


def _grow_settings(**values) -> PhotonSettings:
    s = PhotonSettings(enabled="on", photons=2048, refine_photons=16384, radius_m=0.4)
    for key, value in values.items():
        setattr(s, key, value)
    return s


def test_merged_maps_weigh_their_photons_by_their_paths():
    a = PhotonMap(np.zeros((2, 3)), np.full((2, 3), 3.0), np.zeros(2, np.uint32), emitted=100)
    b = PhotonMap(np.ones((1, 3)), np.full((1, 3), 6.0), np.zeros(1, np.uint32), emitted=300)
    m = merge(a, b)
    assert m.emitted == 400 and len(m) == 3
    # each photon's power times its map's share of the paths: 3 * 1/4, 6 * 3/4
    assert np.allclose(m.power, [[0.75] * 3, [0.75] * 3, [4.5] * 3])
    assert merge(a, PhotonMap.empty()).power.sum() == a.power.sum()  # no paths: nothing added


def test_a_grown_map_holds_all_its_paths_and_is_closer_to_the_converged_light():
    scene, s = box_room(), _grow_settings(refine_photons=65536)
    service = PhotonService()
    traced = service.ensure(s, scene)
    grown = service.ensure(s, scene, refined=True)
    assert traced is not None and grown is not None
    assert traced.emitted == 2048 and grown.emitted == 65536
    assert len(grown) == pytest.approx(32 * len(traced), rel=0.2)
    assert len(np.unique(grown.positions, axis=0)) == len(grown)  # new seeds: new photons
    # The same light as one trace of all those paths (the stored flux within 3 %).
    one = trace_photons(scene, 65536, 0)
    assert grown.power.sum() == pytest.approx(one.power.sum(), rel=0.03)
    # Smoother: the cache's bounced light on the floor is nearer a converged map's.
    converged = cache_for(trace_photons(scene, 1 << 18, 5), s.radius_m)
    rng = np.random.default_rng(3)
    floor = np.column_stack(
        [rng.uniform(-2.5, 2.5, 400), np.zeros(400), rng.uniform(-2.5, 4.5, 400)]
    )
    up = np.tile([0.0, 1.0, 0.0], (400, 1))
    truth = converged.lookup(floor, up)

    def error(photons) -> float:
        return float(np.abs(cache_for(photons, s.radius_m).lookup(floor, up) - truth).mean())

    assert error(grown) < 0.6 * error(traced), (error(grown), error(traced))
    # Deterministic: another service grows the same bytes; without refined, the traced map.
    again = PhotonService()
    assert again.ensure(s, scene) is not None
    assert np.array_equal(again.ensure(s, scene, refined=True).positions, grown.positions)
    assert service.ensure(s, scene) is traced


def test_the_map_grows_in_the_background_only_while_the_viewer_rests():
    scene, s = box_room(), _grow_settings()
    service = PhotonService()
    try:
        _wait(lambda: service.poll(s, scene) is not None)
        for _ in range(5):  # walking: the map stays as traced, nothing runs
            assert service.poll(s, scene, rest=False).emitted == 2048
            assert not service.tracing
        # Standing: doubled each step (4096, 8192, 16384), then no further.
        seen = set()
        _wait(lambda: seen.add(service.poll(s, scene, rest=True).emitted) or 16384 in seen, 30)
        assert seen <= {2048, 4096, 8192, 16384}
        assert service.poll(s, scene, rest=True).emitted == 16384 and not service.tracing
        s.refine_photons = 4096  # asked for less than it has: the traced map again
        assert service.poll(s, scene, rest=False).emitted == 2048
        s.indirect = "gather"  # the per-pixel gather keeps its photon count
        assert indirect.refine_target(s) == 2048
        assert service.poll(s, scene, rest=True).emitted == 2048 and not service.tracing
    finally:
        service.close()


def test_walking_cancels_a_growth_step_and_keeps_the_map(tracer, monkeypatch):
    tracer.release.set()
    started = threading.Event()

    def slow_grow(settings, scene, base, cancel=None, daylight=None, progress=None):
        started.set()
        while not cancel():
            time.sleep(0.005)
        raise TracingCancelled("cancelled")

    monkeypatch.setattr(indirect, "grow", slow_grow)
    service, s, scene = PhotonService(), _grow_settings(), _scene()
    try:
        _wait(lambda: service.poll(s, scene) is not None)
        traced = service.map
        service.poll(s, scene, rest=True)
        assert started.wait(5) and service.refining
        _wait(lambda: (service.poll(s, scene, rest=False), not service.tracing)[1])
        assert service.map is traced and service.take_error() is None
    finally:
        service.close()
