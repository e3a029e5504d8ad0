"""The measurement behind render.sharpen (RCAS after EASU; not a test: a script).

For each scene, the first frame of its path at 2x640x720 drawn at full resolution, then at
render.scale 0.67 and 0.5 enlarged bilinearly, with EASU, and with EASU + RCAS folded into the
upscale pass or in its own pass at the drawn size (render.sharpen 0.9 = FSR's 0.2 stops,
and 1.0 = 0 stops): FLIP against the full
frame, and the present pass's GPU time (median of ``repeats`` frames; at 1.0 the plain
present, which is also what one more full-screen pass at the view's size costs here).

    PYTHONPATH=. VRPREVIEW_SCENES=/work/shared/scenes python tests/measure_rcas.py \
        [scene ...] [--repeats N]
"""

import statistics
import sys

from app import metrics
from app.lab.bench import _open
from app.settings import Settings

SIZE = (1280, 720)
VARIANTS = (
    ("bilinear", {"render.upscaler": "bilinear", "render.sharpen": 0.0}),
    ("easu", {"render.upscaler": "edge", "render.sharpen": 0.0}),
    ("rcas pass 0.2 stops", {"render.upscaler": "edge", "render.sharpen": 0.9}),
    ("rcas pass 0 stops", {"render.upscaler": "edge", "render.sharpen": 1.0}),
    ("rcas folded 0.2 st", {"render.upscaler": "edge", "render.sharpen": 0.9, "at": "folded"}),
    ("rcas after 0.2 st", {"render.upscaler": "edge", "render.sharpen": 0.9, "at": "after"}),
)


def measure(scene_name: str, repeats: int) -> None:
    settings = Settings()
    _scene, session, host, _load = _open(scene_name, SIZE, settings)
    try:
        session.apply_path_frame(0)
        host.set_text_image(None)
        frame = session.frame_input(*host.eye_size)
        ppd = metrics.pixels_per_degree(
            SIZE[0] // 2, session.camera.horizontal_fov_deg(SIZE[0] // 2, SIZE[1])
        )

        present = host.renderer.pass_named("present")

        def shot(values: dict) -> tuple:
            values = dict(values)
            present.rcas_placement = values.pop("at", "pass")
            for key, value in values.items():
                host.settings.set(key, value)
            img = host.draw(frame)
            ms = []
            for _ in range(repeats):
                host.render_only(frame)
                ms.append(host.renderer.pass_ms().get("present", float("nan")))
            return img, statistics.median(ms)

        full, full_ms = shot({"render.scale": 1.0})
        print(f"{scene_name}: full resolution, present {full_ms:.2f} ms")
        for scale in (0.67, 0.5):
            for label, values in VARIANTS:
                img, ms = shot({"render.scale": scale, **values})
                err = metrics.flip(full, img, ppd)
                print(f"  scale {scale:<4} {label:<20} FLIP {err:.4f}  present {ms:.2f} ms")
    finally:
        host.close()


def main(argv: list[str]) -> None:
    repeats = 9
    if "--repeats" in argv:
        i = argv.index("--repeats")
        repeats = int(argv[i + 1])
        argv = argv[:i] + argv[i + 2 :]
    for name in argv or ["showroom", "/work/shared/scenes/interiors/bathroom/bathroom.gltf"]:
        measure(name, repeats)


if __name__ == "__main__":
    main(sys.argv[1:])
