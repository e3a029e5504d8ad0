"""The frame's targets kept for the last sizes drawn (render.pass_graph.BySize): the render
scale the governor steps back to and the warm-up's small frames do not remake every target."""

import numpy as np

from render.pass_graph import BySize


class _Made:
    def __init__(self, size):
        self.size = size
        self.released = False

    def release(self):
        self.released = True


def test_the_last_sizes_are_kept_and_the_least_recently_used_released():
    made: list[_Made] = []

    def make(size):
        made.append(_Made(size))
        return made[-1]

    cache = BySize(make, lambda item: item.release(), keep=2)
    a = cache.get((64, 48))
    b = cache.get((32, 24))
    assert cache.get((64, 48)) is a and len(made) == 2  # kept: not made again
    c = cache.get((16, 12))  # a third size: the least recently used (32x24) goes
    assert b.released and not a.released and not c.released
    assert cache.sizes() == [(64, 48), (16, 12)]
    cache.drop((64, 48))
    assert a.released and cache.get((64, 48)) is not a
    cache.clear()
    assert all(m.released for m in made) and cache.sizes() == []


def test_a_scale_drawn_again_reuses_its_targets_and_draws_the_same_picture(edge_host):
    host = edge_host
    from tests.test_governor import draw

    half = draw(host, 0.5)
    kept = list(host.renderer.targets)
    full = draw(host, 1.0)
    assert host.renderer.targets[0] is not kept[0]  # the view's size has its own
    again = draw(host, 0.5)
    assert host.renderer.targets == kept  # the same textures, not made anew
    assert np.array_equal(again, half)
    assert not np.array_equal(full, half)


def test_coarse_shading_history_is_forgotten_when_a_kept_size_returns(edge_host):
    """The temporal filter blends the last frame of the same size: after frames of another
    size, what it kept is not the last frame, so the targets come back without history."""
    from tests.test_governor import draw

    host = edge_host
    host.settings.set("cps.mode", "cps")
    host.settings.set("cps.temporal", True)
    try:
        draw(host, 0.5)
        draw(host, 0.5)
        cps = host.renderer.cps
        kept = list(cps.eyes)
        assert all(e.has_history for e in kept)
        draw(host, 1.0)
        host.renderer._ensure_targets(*kept[0].size)  # what the next 0.5 frame does first
        cps.ensure(host.renderer.targets)
        assert cps.eyes == kept and not any(e.has_history for e in kept)
    finally:
        host.settings.set("cps.mode", "none")
        host.settings.set("cps.temporal", False)


def test_frames_without_coarse_shading_make_no_coarse_shading_targets(edge_host):
    """The CPS targets are made when a CPS pass first asks, not with each new render scale:
    with coarse shading off, a new scale's first frame made them for nothing (6-8 ms at the
    governor's scales on llvmpipe, 75 ms at 640x720)."""
    from tests.test_governor import draw

    host = edge_host
    host.renderer.cps.release()
    draw(host, 0.5)
    draw(host, 1.0)
    assert host.renderer.cps._by_size.sizes() == []
    host.settings.set("cps.mode", "cps")
    try:
        draw(host, 0.5)
        made = host.renderer.cps._by_size.sizes()
        assert made == [host.renderer.targets[0].size]
        assert host.renderer.cps.read_levels()  # the coarse-shading frame drew its levels
    finally:
        host.settings.set("cps.mode", "none")
