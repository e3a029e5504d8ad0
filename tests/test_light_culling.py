"""Tiled light culling: the same picture, far fewer light evaluations, never a dropped light."""

from __future__ import annotations

import numpy as np
import pytest

from app.scene import PointLight
from app.scenes import resolve
from app.session import Session
from app.settings import Settings
from render.offscreen import OffscreenHost
from tests.test_render import checker_scene

W, H = 320, 180


def frame_of(host: OffscreenHost, scene, n: int = 120):
    session = Session(host.settings.copy())
    session.set_scene(scene)
    session.apply_path_frame(n)
    return session.frame_input(*host.eye_size)


def render(host: OffscreenHost, fi, **values) -> np.ndarray:
    for key, value in values.items():
        host.settings.set(key.replace("__", "."), value)
    return host.draw(fi)


@pytest.mark.parametrize("name", ["showroom-100", "corridor"])
@pytest.mark.parametrize("lighting", ["compute", "fragment"])
def test_culling_keeps_the_picture_and_cuts_light_evaluations(name, lighting):
    scene = resolve(name)
    s = Settings()
    s.render.overlay = False
    s.render.lighting = lighting
    with OffscreenHost(W, H, s) as host:
        host.set_scene(scene)
        fi = frame_of(host, scene)
        culled = render(host, fi, render__light_culling=True)
        with host.ctx:
            work = host.renderer.light_evaluations()
        full = render(host, fi, render__light_culling=False)
        assert np.abs(culled.astype(int) - full.astype(int)).max() <= 1
        # The corridor's lights reach a few metres of a 40 m hall; the showroom's 2.5 m lights
        # reach a quarter of its 8 m room from anywhere: even exact per-pixel range culling
        # cuts only 4.3-5.3x there (tiles: 3.8-4.5x at 1280x720).
        factor = 5 if name == "corridor" else 2.5
        assert work["all"] >= factor * work["culled"] > 0, work
        # Coarse shading reads the same lists.
        render(host, fi, cps__mode="cps", render__light_culling=True)
        a = host.draw(fi)
        b = render(host, fi, render__light_culling=False)
        assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
        assert not host.renderer.errors


def test_a_tile_with_more_lights_than_its_list_holds_uses_every_light():
    scene = checker_scene()
    scene.lights = [
        PointLight((0.02 * i - 1.5, 1.6, -0.5), (1.0, 0.9, 0.8), 0.2, 50.0) for i in range(150)
    ]  # every light reaches every pixel: > 128 per tile
    s = Settings()
    s.render.overlay = False
    with OffscreenHost(W, H, s) as host:
        host.set_scene(scene)
        fi = frame_of(host, scene, 0)
        culled = render(host, fi, render__light_culling=True)
        with host.ctx:
            work = host.renderer.light_evaluations()
        full = render(host, fi, render__light_culling=False)
        assert work["culled"] == work["all"] > 0
        assert np.abs(culled.astype(int) - full.astype(int)).max() <= 1
        assert culled.max() > 100
