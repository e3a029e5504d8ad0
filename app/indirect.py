"""When a scene gets photon-mapped indirect light, and the photon map it gets.

Model only what a scene requires: no photon map is traced unless the scene asks for one
(``Scene.indirect``) or the user turns it on (``photons.enabled = on``). The map is traced again
only when what it depends on changes (the scene's geometry and lights, the photon count, the
seed, the path length, and with daylight on the sun and the sky: a new time of day, date or
site traces again); the radius and the gather variant only rebuild the grid on the GPU side,
and the dimmer scales the indirect light in the shader.

**Refining while the viewer stands** (issue 15, "indirect light converging"): with the
precomputed method (``photons.indirect = cache``) a map grows while the viewpoint rests, up to
``photons.refine_photons`` paths. Each step traces as many paths again as the map has, with the
next seed (``refine_seed``), merges the two (``app.photon_map.merge``: each weighted by its
share of the paths, so the result is the estimate of all of them) and builds the cache over
all; the renderer then swaps the map in. The noise of the bounced light halves in variance each
step (at 1M paths the daylit staircase's blotchy ceiling is smooth; standing, its FLIP against
Cycles goes 0.289 -> 0.244: docs/reference_flip.md, "Stop 37"). Walking cancels a step (the
frames keep both cores) and keeps the map grown so far; a change of what the map depends on
starts again from the traced map. The per-pixel gather keeps its photon count (its cost grows
with every photon in the radius). Headless hosts trace the grown map at once when asked
(``ensure(..., refined=True)``: the picture a viewer gets after standing, deterministic).
"""

from __future__ import annotations

import concurrent.futures
import copy
import logging
import time
from collections.abc import Callable

from app.daylight_photons import Daylight, daylight_for
from app.photon_map import PhotonMap, merge
from app.scene import Scene
from app.settings import PhotonSettings, SkySettings
from app.sky import scene_sky

log = logging.getLogger(__name__)


def wanted(settings: PhotonSettings, scene: Scene | None) -> bool:
    """Whether this scene gets indirect light under these settings."""
    if scene is None or settings.enabled == "off" or settings.photons <= 0:
        return False
    return settings.enabled == "on" or scene.indirect


def refine_target(settings: PhotonSettings) -> int:
    """The photon paths a map grows to while the viewer stands (the traced count where the
    method is the per-pixel gather, or ``refine_photons`` is not above it)."""
    if settings.indirect != "cache":
        return max(0, int(settings.photons))
    return max(int(settings.photons), int(settings.refine_photons))


def refine_seed(seed: int, emitted: int) -> int:
    """The seed of the paths that grow a map of ``emitted`` paths traced from ``seed``: one
    per step, none equal to a map's own (deterministic, so a grown map is reproducible)."""
    return (int(seed) + 0x9E3779B1 * max(1, int(emitted).bit_length())) % (1 << 31)


def map_key(
    settings: PhotonSettings, scene: Scene | None, daylight: Daylight | None = None
) -> tuple:
    """Everything the traced photons depend on (the scene by identity: scenes are not edited in
    place; a reload is a new object; the cache holds the scene, so its id is not reused), and
    the daylight (sun and sky) when ``sky.enabled``."""
    key: tuple = (id(scene), settings.photons, settings.seed, settings.max_bounces)
    return key if daylight is None else (*key, daylight)


class PhotonService:
    """The current scene's photon map: knows when a new one is needed, traces it, keeps it.

    Two ways to trace, one cache. :meth:`ensure` traces blocking (the offscreen host, before a
    frame). :meth:`poll` traces on a worker thread (the window, from its timer): it starts a
    trace when the map is missing, cancels one the settings or the scene have moved past (the
    new one starts once the old has stopped), and hands a finished map over. While it runs,
    :attr:`tracing` is true and :attr:`progress` is the fraction done. A failed trace is not
    retried for the same key; :meth:`take_error` returns its message once.

    ``sky`` returns the current ``sky.*`` settings (the host's): with daylight on, the sun and the
    sky emit photons too (``app.daylight_photons``) and a change of them traces again.
    """

    def __init__(self, sky: Callable[[], SkySettings | None] | None = None) -> None:
        self.sky = sky
        self.key: tuple | None = None
        self.map: PhotonMap | None = None  # the map shown: the traced one, or grown from it
        self.traced: PhotonMap | None = None  # the map as traced for ``key``
        self.scene: Scene | None = None  # held so that id(scene) in the key stays unique
        self.trace_ms = 0.0
        self.progress = 0.0
        self.failed_key: tuple | None = None
        self._error: str | None = None
        self._grow_failed = False  # a growth step failed: the map stays as it is
        self._executor: concurrent.futures.ThreadPoolExecutor | None = None
        # (future, key, scene, cancel flag, start time, the map it grows or None: a trace) of
        # the job on the worker thread
        self._job: _Job | None = None

    def daylight(self, scene: Scene | None = None) -> Daylight | None:
        """The sun and sky that the photons of ``scene`` get now (None: daylight off, or no
        sky given); a scene's own north turns them (``app.sky.scene_sky``)."""
        if self.sky is None:
            return None
        sky = self.sky()
        if sky is None or not sky.enabled:
            return None
        return daylight_for(scene_sky(sky, scene))

    def key_for(self, settings: PhotonSettings, scene: Scene | None) -> tuple:
        return map_key(settings, scene, self.daylight(scene))

    def current(self, settings: PhotonSettings, scene: Scene | None) -> PhotonMap | None:
        """The map for these settings if it is already traced (never traces): the grown one,
        unless it grew past what the settings now ask for (then the traced one)."""
        if not wanted(settings, scene) or self.key != self.key_for(settings, scene):
            return None
        if self.map is not None and self.map.emitted > refine_target(settings):
            self.map = self.traced
        return self.map

    @property
    def refining(self) -> bool:
        """Whether the worker is growing the map (not tracing a new one)."""
        return self._job is not None and self._job[5] is not None

    def ensure(
        self,
        settings: PhotonSettings,
        scene: Scene | None,
        progress: Callable[[float], None] | None = None,
        cancel: Callable[[], bool] | None = None,
        refined: bool = False,
    ) -> PhotonMap | None:
        """The map for these settings, traced here and now (blocking) if needed; ``refined``:
        grown to ``refine_target`` as a viewer standing still gets it."""
        if not wanted(settings, scene):
            return None
        assert scene is not None
        daylight = self.daylight(scene)
        key = map_key(settings, scene, daylight)
        if self.key != key:
            start = time.perf_counter()
            extra = {} if daylight is None else {"daylight": daylight}
            photons = trace(settings, scene, progress, cancel, **extra)
            self.store(key, scene, photons)
            self.trace_ms = (time.perf_counter() - start) * 1e3
        current = self.current(settings, scene)
        while refined and current is not None and grows(settings, current):
            current = self.map = grow(settings, scene, current, cancel, daylight)
        return self.map if refined else self.traced

    def store(self, key: tuple, scene: Scene, photons: PhotonMap) -> None:
        """Keep a map (traced here, or elsewhere for these settings and scene)."""
        self.key, self.scene, self.map, self.traced = key, scene, photons, photons
        self._grow_failed = False

    # -- tracing in the background -------------------------------------------------------------
    @property
    def tracing(self) -> bool:
        """Whether a trace is running on the worker thread."""
        return self._job is not None

    def failed(self, settings: PhotonSettings, scene: Scene | None) -> bool:
        """Whether tracing for these settings and scene failed (and is not retried)."""
        return scene is not None and self.failed_key == self.key_for(settings, scene)

    def take_error(self) -> str | None:
        """The message of a trace that failed since the last call, once."""
        error, self._error = self._error, None
        return error

    def poll(
        self, settings: PhotonSettings, scene: Scene | None, rest: bool = False
    ) -> PhotonMap | None:
        """Advance the background work; returns the map to show now (None: no indirect light).

        Never blocks: collects a finished trace or growth step, cancels one that is no longer
        wanted (a growth step also when the viewer moves: ``rest`` false), starts a trace when
        these settings need a map that is neither traced nor failed, and, while the viewer
        rests, a growth step towards ``refine_target``.
        """
        if self._job is not None:
            future, key, traced_scene, cancel, started, base = self._job
            if not future.done():
                moved_on = not wanted(settings, scene) or key != self.key_for(settings, scene)
                if moved_on or (base is not None and not rest):
                    cancel[0] = True  # stop; then trace what is wanted now
                return self.current(settings, scene)
            self._job = None
            from app.photons import TracingCancelled  # loaded with the tracer, not before

            try:
                photons = future.result()
            except TracingCancelled:
                pass
            except Exception as exc:  # noqa: BLE001 - a tracer bug must not take the host down
                log.exception("photon tracing failed")
                if base is None:  # a failed growth step keeps the map it had
                    self.failed_key = key
                self._error = f"{traced_scene.name}: {exc}"
                self._grow_failed = base is not None
            else:
                if base is None:
                    self.store(key, traced_scene, photons)
                    self.trace_ms = (time.monotonic() - started) * 1e3
                elif key == self.key and base is self.map:
                    self.map = photons
        current = self.current(settings, scene)
        if current is None and wanted(settings, scene) and not self.failed(settings, scene):
            self._start(settings, scene)
        elif current is not None and rest and self._job is None and not self._grow_failed:
            if grows(settings, current):
                self._start(settings, scene, current)
        return current

    def _start(
        self, settings: PhotonSettings, scene: Scene | None, base: PhotonMap | None = None
    ) -> None:
        """Trace a map for these settings on the worker thread, or grow ``base`` by a step."""
        assert scene is not None
        if self._executor is None:
            self._executor = concurrent.futures.ThreadPoolExecutor(
                max_workers=1, thread_name_prefix="photons"
            )
        cancel = [False]
        self.progress = 0.0

        def progress(fraction: float) -> None:
            self.progress = fraction  # read by the host's poll; a float store is atomic

        # A copy: the settings may change while the worker reads them (a Daylight is frozen).
        daylight = self.daylight(scene)
        mine = copy.copy(settings)
        if base is None:
            extra = {} if daylight is None else {"daylight": daylight}
            future = self._executor.submit(trace, mine, scene, progress, lambda: cancel[0], **extra)
        else:
            future = self._executor.submit(
                grow, mine, scene, base, lambda: cancel[0], daylight, progress
            )
        key = map_key(settings, scene, daylight)
        self._job = (future, key, scene, cancel, time.monotonic(), base)

    def close(self) -> None:
        """Cancel a running trace and let the worker thread go (without waiting for it)."""
        if self._job is not None:
            self._job[3][0] = True
        if self._executor is not None:
            self._executor.shutdown(wait=False, cancel_futures=True)
            self._executor = None


_Job = tuple[concurrent.futures.Future, tuple, Scene, list[bool], float, "PhotonMap | None"]


def grows(settings: PhotonSettings, photons: PhotonMap) -> bool:
    """Whether a map of these settings grows further while the viewer stands (a map with no
    light, or no photon stored, stays as it is)."""
    return 0 < photons.emitted < refine_target(settings) and len(photons) > 0


def grow(
    settings: PhotonSettings,
    scene: Scene,
    base: PhotonMap,
    cancel: Callable[[], bool] | None = None,
    daylight: Daylight | None = None,
    progress: Callable[[float], None] | None = None,
) -> PhotonMap:
    """``base`` grown by one step: as many paths again (at most up to ``refine_target``),
    traced with ``refine_seed``, merged, and its cache built (on the worker thread)."""
    count = min(base.emitted, refine_target(settings) - base.emitted)
    seed = refine_seed(settings.seed, base.emitted)
    return _traced(settings, scene, count, seed, progress, cancel, daylight, base)


def trace(
    settings: PhotonSettings,
    scene: Scene,
    progress: Callable[[float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
    daylight: Daylight | None = None,
) -> PhotonMap:
    """The map of these settings (its cache built too: on the worker thread, not in the
    first frame)."""
    return _traced(settings, scene, settings.photons, settings.seed, progress, cancel, daylight)


def _traced(
    settings: PhotonSettings,
    scene: Scene,
    count: int,
    seed: int,
    progress: Callable[[float], None] | None,
    cancel: Callable[[], bool] | None,
    daylight: Daylight | None,
    base: PhotonMap | None = None,
) -> PhotonMap:
    """``count`` paths traced from ``seed`` (merged into ``base`` when given), and for the
    precomputed method their cache."""
    from app.photons import trace_photons  # embree is loaded only when photons are wanted

    start = time.perf_counter()
    photons = trace_photons(
        scene,
        count,
        seed,
        max_bounces=settings.max_bounces,
        progress=progress,
        cancel=cancel,
        daylight=daylight,
    )
    if base is not None:
        photons = merge(base, photons)
    if settings.indirect == "cache":
        from app.irradiance_cache import cache_for

        cache_for(photons, settings.radius_m)
    log.info(
        "traced %d photon paths in %s (%d in the map): %d photons stored, %.0f ms",
        count,
        scene.name,
        photons.emitted,
        len(photons),
        (time.perf_counter() - start) * 1e3,
    )
    return photons
