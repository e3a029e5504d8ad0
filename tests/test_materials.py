"""glTF materials shaded per pixel: normal, metallic-roughness, occlusion and emissive maps, alpha
MASK and BLEND, in the deferred and forward paths and under coarse pixel shading; tangents from
the file or generated; the glTF reader keeps every map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from app.camera import StereoCamera
from app.frame import FrameInput
from app.loaders import LoadOptions, load_scene
from app.scene import Material, Mesh, PointLight, Scene, Texture, Viewpoint
from app.settings import Settings
from app.tangents import generate_tangents
from render.offscreen import OffscreenHost

W, H = 320, 180  # two 160x180 eyes
PATHS = [
    pytest.param({"render__path": "deferred"}, id="deferred"),
    pytest.param({"render__path": "forward"}, id="forward"),
    pytest.param({"render__path": "deferred", "cps__mode": "cps"}, id="cps"),
]


def wall(name: str, z: float, half: float, material: int = 0, cx: float = 0.0) -> Mesh:
    """A square facing +Z (the camera) at depth z, centred at (cx, 1.6); u right, v up."""
    pos = np.array(
        [
            [cx - half, 1.6 - half, z],
            [cx + half, 1.6 - half, z],
            [cx + half, 1.6 + half, z],
            [cx - half, 1.6 + half, z],
        ],
        np.float32,
    )
    return Mesh(
        name,
        pos,
        np.tile([0, 0, 1], (4, 1)).astype(np.float32),
        np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
        material,
    )


def stripes(left: tuple[int, ...], right: tuple[int, ...], n: int = 8) -> np.ndarray:
    """An n x n RGBA image of vertical stripes, two texels wide, alternating left / right."""
    img = np.zeros((n, n, 4), np.uint8)
    for x in range(n):
        img[:, x] = (*left, 255) if (x // 2) % 2 == 0 else (*right, 255)
    return img


def halves(left: tuple[int, ...], right: tuple[int, ...], n: int = 8) -> np.ndarray:
    img = np.zeros((n, n, 4), np.uint8)
    img[:, : n // 2] = (*left, 255)[:4]
    img[:, n // 2 :] = (*right, 255)[:4]
    return img


@pytest.fixture(scope="module")
def host():
    h = OffscreenHost(W, H, Settings())
    yield h
    assert not h.renderer.errors
    h.close()


def draw(host: OffscreenHost, scene: Scene, **settings) -> np.ndarray:
    """The left eye (H, W/2, 3) of one frame, viewed from (0, 1.6, 0) down -Z, eyes together."""
    s = host.settings
    defaults = Settings()
    for key in (
        "render.path",
        "render.lighting",
        "cps.mode",
        "render.ambient",
        "render.normal_maps",
    ):
        s.set(key, defaults.get(key))
    s.set("stereo.ipd_mm", 0.0)
    s.set("render.ambient_estimate", False)  # the fixed ambient light these scenes are lit by
    # The material's colours as they are: no filmic curve desaturating a bright glow, and white
    # at 1.2 cd/m2 (EV 0), close to the old curve's.
    s.set("render.tone_mapping", "clamp")
    s.set("render.exposure_ev", 0.0)
    for key, value in settings.items():
        s.set(key.replace("__", "."), value)
    host.set_scene(scene)
    host.set_text_image(None)
    cam = StereoCamera(s.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    img = host.draw(FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1)))
    return img[:, : W // 2, :3].astype(float)


def pixel_of(host: OffscreenHost, x: float, y: float, z: float) -> tuple[int, int]:
    """(row, column) of world point (x, 1.6 + y, z) in the left eye."""
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    eye = cam.eyes(*host.eye_size)[0]
    clip = eye.view_projection @ np.array([x, 1.6 + y, z, 1.0])
    u = (clip[0] / clip[3] + 1) / 2 * eye.width
    v = (1 - clip[1] / clip[3]) / 2 * eye.height
    return int(v), int(u)


def lit_wall(material: Material, textures: list[Texture], light: PointLight) -> Scene:
    return Scene(
        "wall", [wall("wall", -2.0, 1.0)], [material], textures, [light], Viewpoint((0, 1.6, 0))
    ).sanitized()


# Light from the left, almost in the wall's plane: a flat wall is nearly dark, a normal tilted
# towards the light catches it.
GRAZING = PointLight((-2.5, 1.6, -1.9), (1, 1, 1), 40.0, 20.0)
TILT_LEFT = (38, 128, 220)  # normal map texels: tilted towards -X (the light), and +X
TILT_RIGHT = (218, 128, 220)


@pytest.mark.parametrize("path", PATHS)
def test_normal_map_shades_a_plane_per_pixel_under_a_grazing_light(host, path):
    grey = Material("plaster", (0.8, 0.8, 0.8, 1.0), roughness=1.0)
    flat = draw(host, lit_wall(grey, [], GRAZING), render__ambient=0.0, **path)
    bumpy_mat = Material("plaster", (0.8, 0.8, 0.8, 1.0), roughness=1.0, normal_texture=0)
    tex = [Texture("bumps", stripes(TILT_LEFT, TILT_RIGHT), repeat=False)]
    bumpy = draw(host, lit_wall(bumpy_mat, tex, GRAZING), render__ambient=0.0, **path)
    r0, c0 = pixel_of(host, -0.9, 0.3, -2.0)
    r1, c1 = pixel_of(host, 0.9, -0.3, -2.0)
    row_flat = flat[r0:r1, c0:c1].mean(axis=(0, 2))  # mean over rows: one value per column
    row_bumpy = bumpy[r0:r1, c0:c1].mean(axis=(0, 2))
    # The stripes facing the light are much brighter than the flat wall; their neighbours
    # (facing away) are darker than it: the picture has the map's stripes, not a flat shade.
    assert row_bumpy.max() > row_flat.max() + 40, (row_flat.max(), row_bumpy.max())
    assert row_bumpy.min() <= row_flat.min() + 2
    assert np.abs(np.diff(row_bumpy)).max() > 30  # stripe edges
    assert np.abs(np.diff(row_flat)).max() < 6


@pytest.mark.parametrize("path", PATHS)
def test_surface_relief_off_shades_a_normal_mapped_plane_as_flat(host, path):
    """render.normal_maps ("Surface relief"): on, the grazing light picks out the map's
    stripes; off, the same material shades as the plane without its map, in every path."""
    grey = Material("plaster", (0.8, 0.8, 0.8, 1.0), roughness=1.0)
    flat = draw(host, lit_wall(grey, [], GRAZING), render__ambient=0.0, **path)
    bumpy_mat = Material("plaster", (0.8, 0.8, 0.8, 1.0), roughness=1.0, normal_texture=0)
    tex = [Texture("bumps", stripes(TILT_LEFT, TILT_RIGHT), repeat=False)]
    scene = lit_wall(bumpy_mat, tex, GRAZING)
    on = draw(host, scene, render__ambient=0.0, render__normal_maps=True, **path)
    off = draw(host, scene, render__ambient=0.0, render__normal_maps=False, **path)
    r0, c0 = pixel_of(host, -0.9, 0.3, -2.0)
    r1, c1 = pixel_of(host, 0.9, -0.3, -2.0)
    on_wall, off_wall, flat_wall = (a[r0:r1, c0:c1] for a in (on, off, flat))
    assert flat_wall.max() > 5  # the grazing light reaches the flat wall a little
    assert np.abs(on_wall - off_wall).max() > 40  # the relief shows with the setting on
    assert np.abs(on_wall - off_wall).mean() > 10
    assert np.abs(off_wall - flat_wall).max() <= 1  # and is gone with it off


@pytest.mark.parametrize("path", PATHS[:2])
def test_flat_normal_map_looks_like_no_normal_map(host, path):
    light = PointLight((-1.5, 1.6, -0.5), (1, 1, 1), 20.0, 20.0)
    grey = Material("plaster", (0.8, 0.8, 0.8, 1.0), roughness=0.5)
    plain = draw(host, lit_wall(grey, [], light), **path)
    flat_mat = Material("plaster", (0.8, 0.8, 0.8, 1.0), roughness=0.5, normal_texture=0)
    tex = [Texture("flat", stripes((128, 128, 255), (128, 128, 255)), repeat=False)]
    mapped = draw(host, lit_wall(flat_mat, tex, light), **path)
    assert plain.max() > 60  # lit: the comparison means something
    assert np.abs(plain - mapped).mean() < 0.5
    assert np.abs(plain - mapped).max() <= 3


@pytest.mark.parametrize("path", PATHS[:2])
def test_metallic_roughness_map_changes_the_highlight_per_pixel(host, path):
    # Left half glossy, right half rough (G = roughness); a lamp straight in front: the
    # highlight's peak is sharp on the left and spread out on the right.
    light = PointLight((0.0, 1.6, -0.8), (1, 1, 1), 6.0, 20.0)
    mat = Material(
        "varnish", (0.3, 0.3, 0.3, 1.0), roughness=1.0, metallic=0.0, metallic_roughness_texture=0
    )
    tex = [Texture("mr", halves((0, 40, 0), (0, 255, 0)), repeat=False)]
    img = draw(host, lit_wall(mat, tex, light), render__ambient=0.0, **path).mean(axis=2)
    r, c = pixel_of(host, 0.0, 0.0, -2.0)
    glossy_near = img[r, c - 3]  # just left of the centre
    rough_near = img[r, c + 3]
    assert glossy_near > rough_near + 25, (glossy_near, rough_near)
    uniform = draw(
        host, lit_wall(Material("varnish", (0.3, 0.3, 0.3, 1.0), 1.0), [], light), **path
    )
    u = uniform.mean(axis=2)
    assert abs(u[r, c - 3] - u[r, c + 3]) < 3  # without the map both sides match


@pytest.mark.parametrize("path", PATHS)
def test_emissive_map_glows_where_the_map_is_bright(host, path):
    mat = Material("sign", (0.0, 0.0, 0.0, 1.0), emissive=(0.0, 4.0, 0.0), emissive_texture=0)
    tex = [Texture("glow", halves((0, 0, 0), (255, 255, 255)), repeat=False)]
    scene = Scene("sign", [wall("sign", -2.0, 1.0)], [mat], tex, [], Viewpoint((0, 1.6, 0)))
    img = draw(host, scene.sanitized(), render__ambient=0.0, **path)
    r, c_dark = pixel_of(host, -0.5, 0.0, -2.0)
    _, c_bright = pixel_of(host, 0.5, 0.0, -2.0)
    assert img[r, c_bright, 1] > 150 and img[r, c_bright, 0] < 40, img[r, c_bright]
    assert img[r, c_dark].max() < 10, img[r, c_dark]


def test_occlusion_map_darkens_the_ambient_light(host):
    mat = Material("corner", (0.8, 0.8, 0.8, 1.0), occlusion_texture=0)
    tex = [Texture("ao", halves((40, 0, 0), (255, 0, 0)), repeat=False)]
    scene = Scene("ao", [wall("w", -2.0, 1.0)], [mat], tex, [], Viewpoint((0, 1.6, 0)))
    for path in PATHS[:2]:
        img = draw(host, scene.sanitized(), render__ambient=1.0, **path.values[0])
        r, c_dark = pixel_of(host, -0.5, 0.0, -2.0)
        _, c_open = pixel_of(host, 0.5, 0.0, -2.0)
        assert img[r, c_open].mean() > img[r, c_dark].mean() + 40, path.id


def background_and_front(
    front: Material, textures: list[Texture], with_front: bool = True
) -> Scene:
    """A red wall 4 m away behind a 'front' square at 2 m; a lamp lights both."""
    red = Material("red wall", (0.9, 0.05, 0.05, 1.0), roughness=1.0)
    meshes = [wall("back", -4.0, 3.0, 0), wall("front", -2.0, 0.6, 1)]
    return Scene(
        "layers",
        meshes if with_front else meshes[:1],
        [red, front],
        textures,
        # 2 lux on the front square 1.5 m away (as 4 cd at 1 m under the old 1 / (d^2 + 1)), 0.37 on
        # the wall 3.5 m away
        [PointLight((0.0, 1.6, -0.5), (1, 1, 1), 4.5, 30.0)],
        Viewpoint((0, 1.6, 0)),
    ).sanitized()


@pytest.mark.parametrize("path", PATHS)
def test_masked_leaves_are_cut_out(host, path):
    # Green leaf texels opaque on the left half, transparent (alpha 0) on the right.
    leaf = np.zeros((8, 8, 4), np.uint8)
    leaf[:, :4] = (40, 200, 40, 255)
    leaf[:, 4:] = (40, 200, 40, 0)
    mat = Material("leaf", (1, 1, 1, 1), 0, roughness=1.0, alpha_mode="MASK", alpha_cutoff=0.5)
    scene = background_and_front(mat, [Texture("leaf", leaf, repeat=False)])
    img = draw(host, scene, **path)
    r, c_leaf = pixel_of(host, -0.3, 0.0, -2.0)
    _, c_hole = pixel_of(host, 0.3, 0.0, -2.0)
    assert img[r, c_leaf, 1] > 2 * img[r, c_leaf, 0], img[r, c_leaf]  # the leaf
    assert img[r, c_hole, 0] > 3 * img[r, c_hole, 1], img[r, c_hole]  # the red wall behind
    ids = host.object_ids(frame_input(host))[0]
    assert ids[r, c_leaf] == 1 and ids[r, c_hole] == 0  # the hole is the wall's pixel


def frame_input(host: OffscreenHost) -> FrameInput:
    cam = StereoCamera(host.settings.stereo)
    cam.set_pose((0, 1.6, 0), 0.0, 0.0)
    return FrameInput(cam.eyes(*host.eye_size), gaze=(-1, -1))


@pytest.mark.parametrize("path", PATHS)
def test_blended_glass_shows_what_lies_behind_tinted(host, path):
    glass = Material("glass", (0.01, 0.1, 0.9, 0.4), roughness=1.0, alpha_mode="BLEND")
    seen = draw(host, background_and_front(glass, []), **path)
    assert "blend" in host.renderer.pass_ms()  # drawn by the blend pass, after the lighting
    opaque = Material("glass", (0.01, 0.1, 0.9, 1.0), roughness=1.0)
    blocked = draw(host, background_and_front(opaque, []), **path)
    no_glass = draw(host, background_and_front(glass, [], with_front=False), **path)
    r, c = pixel_of(host, 0.0, 0.0, -2.0)
    behind, through, wall_px = no_glass[r, c], seen[r, c], blocked[r, c]
    # an opaque pane hides the red wall (its red: the even light its specular lobe reflects) ...
    assert wall_px[0] < 0.6 * behind[0]
    assert through[0] > 0.4 * behind[0] and through[0] > wall_px[0] + 30  # ... glass shows it,
    assert through[2] > behind[2] + 10  # tinted blue


def test_blended_meshes_are_drawn_back_to_front(host):
    # Two panes, the far one red, the near one blue, both half transparent: the near one's
    # colour must dominate whatever order the meshes have in the scene.
    red = Material("red glass", (0.9, 0.05, 0.05, 0.6), roughness=1.0, alpha_mode="BLEND")
    blue = Material("blue glass", (0.05, 0.05, 0.9, 0.6), roughness=1.0, alpha_mode="BLEND")
    light = PointLight((0.0, 1.6, -0.5), (1, 1, 1), 30.0, 30.0)
    for order in ((0, 1), (1, 0)):
        meshes = [wall("far", -3.0, 1.0, 0), wall("near", -2.0, 0.6, 1)]
        scene = Scene(
            "panes",
            [meshes[i] for i in order],
            [red, blue],
            [],
            [light],
            Viewpoint((0, 1.6, 0)),
        ).sanitized()
        img = draw(host, scene)
        r, c = pixel_of(host, 0.0, 0.0, -2.0)
        assert img[r, c, 2] > img[r, c, 0], (order, img[r, c])


# ---- loading -------------------------------------------------------------------------------


def test_tangents_from_the_file_match_generated_ones(scenes_dir):
    path = scenes_dir / "gltf-samples" / "TwoSidedPlane" / "glTF" / "TwoSidedPlane.gltf"
    scene = load_scene(path)
    mesh = scene.meshes[0]
    mat = scene.materials[mesh.material]
    assert mat.normal_texture is not None and mat.metallic_roughness_texture is not None
    assert mat.double_sided
    assert mesh.tangents is not None  # the file's TANGENT attribute
    made = generate_tangents(mesh.positions, mesh.normals, mesh.uvs, mesh.indices)
    dots = np.einsum("ij,ij->i", mesh.tangents[:, :3], made[:, :3])
    assert dots.min() > 0.999, dots


def test_generated_tangents_follow_the_uv_layout():
    quad = wall("q", -2.0, 1.0)
    t = generate_tangents(quad.positions, quad.normals, quad.uvs, quad.indices)
    np.testing.assert_allclose(t, np.tile([1, 0, 0, 1], (4, 1)), atol=1e-6)
    mirrored = quad.uvs.copy()
    mirrored[:, 0] = 1.0 - mirrored[:, 0]  # u runs right to left: tangent -X, handedness -1
    t = generate_tangents(quad.positions, quad.normals, mirrored, quad.indices)
    np.testing.assert_allclose(t, np.tile([-1, 0, 0, -1], (4, 1)), atol=1e-6)
    # All texture coordinates equal (degenerate): a tangent orthogonal to the normal anyway.
    t = generate_tangents(quad.positions, quad.normals, np.zeros_like(quad.uvs), quad.indices)
    assert np.all(np.isfinite(t))
    np.testing.assert_allclose(np.linalg.norm(t[:, :3], axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(t[:, :3] @ np.array([0, 0, 1.0]), 0.0, atol=1e-6)


def _png(rgba: np.ndarray) -> bytes:
    import io

    out = io.BytesIO()
    Image.fromarray(rgba).save(out, "PNG")
    return out.getvalue()


def test_gltf_reader_keeps_every_map_and_the_alpha_modes(tmp_path: Path):
    import base64

    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    nrm = np.tile([0, 0, 1], (4, 1)).astype(np.float32)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    blob = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    views = [(0, 48), (48, 48), (96, 32), (128, 12)]
    orm = np.zeros((4, 4, 4), np.uint8)
    orm[...] = (200, 100, 50, 255)  # occlusion, roughness, metal in one image
    leaf = np.zeros((4, 4, 4), np.uint8)
    leaf[..., 1] = 200
    leaf[:, 2:, 3] = 0
    images = [orm, leaf, np.full((4, 4, 4), 128, np.uint8)]
    for i, img in enumerate(images):
        (tmp_path / f"img{i}.png").write_bytes(_png(img))
    prim = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [
            {
                "byteLength": len(blob),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
            }
        ],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [0, 0, 0],
                "max": [1, 1, 0],
            },
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
        "images": [{"uri": f"img{i}.png"} for i in range(3)],
        "textures": [{"source": i} for i in range(3)],
        "materials": [
            {
                "name": "stone",
                "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 0}},
                "occlusionTexture": {"index": 0, "strength": 0.7},
                "normalTexture": {"index": 2, "scale": 0.5},
                "emissiveTexture": {"index": 1},
                "emissiveFactor": [1, 1, 1],
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5}},
            },
            {
                "name": "leaf",
                "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}},
                "alphaMode": "MASK",
                "alphaCutoff": 0.3,
                "doubleSided": True,
            },
            {
                "name": "glass",
                "alphaMode": "BLEND",
                "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.25]},
            },
        ],
        "meshes": [{"primitives": [{**prim, "material": m}]} for m in range(3)],
        "nodes": [{"mesh": m, "translation": [2.0 * m, 0, 0]} for m in range(3)],
        "scenes": [{"nodes": [0, 1, 2]}],
        "scene": 0,
    }
    path = tmp_path / "maps.gltf"
    path.write_text(json.dumps(doc))
    scene = load_scene(path)
    by_name = {scene.materials[m.material].name: m for m in scene.meshes}
    stone = scene.materials[by_name["stone"].material]
    leaf_mat = scene.materials[by_name["leaf"].material]
    glass = scene.materials[by_name["glass"].material]
    assert stone.metallic_roughness_texture == stone.occlusion_texture  # one image, one texture
    assert stone.occlusion_strength == pytest.approx(0.7)
    assert stone.normal_scale == pytest.approx(0.5)
    assert stone.emissive == pytest.approx((5.0, 5.0, 5.0))
    assert stone.emissive_texture is not None and stone.alpha_mode == "OPAQUE"
    assert by_name["stone"].tangents is not None  # a normal map: a tangent frame
    assert by_name["leaf"].tangents is None  # no normal map: none
    assert (leaf_mat.alpha_mode, leaf_mat.alpha_cutoff, leaf_mat.double_sided) == (
        "MASK",
        pytest.approx(0.3),
        True,
    )
    assert scene.textures[leaf_mat.texture].rgba[0, 3, 3] == 0  # its alpha is kept
    # The emissive use of the same image is colour without alpha: a texture of its own.
    assert scene.textures[stone.emissive_texture].rgba[..., 3].min() == 255
    assert glass.alpha_mode == "BLEND" and glass.base_color[3] == pytest.approx(0.25)
    assert not stone.double_sided


def test_obj_mtl_bump_cutout_glow_and_glass(tmp_path: Path):
    (tmp_path / "room.obj").write_text(
        "mtllib room.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "usemtl stone\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
        "usemtl leaf\nf 1/1/1 2/2/1 3/3/1\n"
        "usemtl glass\nf 1/1/1 3/3/1 4/4/1\n"
    )
    (tmp_path / "room.mtl").write_text(
        "newmtl stone\nKd 0.8 0.8 0.8\nmap_Kd stone.png\nmap_bump -bm 2 stone-bump.png\n"
        "map_Ke glow.png\n"
        "newmtl leaf\nKd 1 1 1\nmap_Kd leaf.png\nmap_d leaf-alpha.png\n"
        "newmtl glass\nKd 0.2 0.4 0.9\nd 0.3\n"
    )
    Image.new("RGB", (8, 8), (120, 110, 100)).save(tmp_path / "stone.png")
    ramp = np.tile(np.arange(8, dtype=np.uint8) * 30, (8, 1))  # rises to the right
    Image.fromarray(ramp, "L").save(tmp_path / "stone-bump.png")
    Image.new("RGB", (8, 8), (255, 200, 100)).save(tmp_path / "glow.png")
    Image.new("RGB", (8, 8), (40, 200, 40)).save(tmp_path / "leaf.png")
    holes = np.zeros((8, 8), np.uint8)
    holes[:, :4] = 255
    Image.fromarray(holes, "L").save(tmp_path / "leaf-alpha.png")
    scene = load_scene(tmp_path / "room.obj")
    mats = {m.name: m for m in scene.materials}
    stone, leaf, glass = mats["stone"], mats["leaf"], mats["glass"]
    assert stone.normal_texture is not None and stone.emissive_texture is not None
    normal = scene.textures[stone.normal_texture].rgba.astype(int)
    # Height rising along +u: the normal leans towards -u (red below 128), not up or down.
    assert normal[4, 4, 0] < 100 and abs(normal[4, 4, 1] - 128) <= 2 and normal[4, 4, 2] > 150
    by_material = {scene.materials[m.material].name: m for m in scene.meshes}
    assert by_material["stone"].tangents is not None and by_material["glass"].tangents is None
    assert leaf.alpha_mode == "MASK" and leaf.texture is not None
    alpha = scene.textures[leaf.texture].rgba[..., 3]
    assert alpha[:, :4].min() == 255 and alpha[:, 4:].max() == 0
    assert glass.alpha_mode == "BLEND" and glass.base_color[3] == pytest.approx(0.3)
    assert stone.alpha_mode == "OPAQUE"


def _two_quads_gltf(tmp_path: Path, materials: list[dict], images: list[np.ndarray]) -> Path:
    """A glTF of two unit quads facing the camera (+Z), uvs 0..1 left to right: a 6 m one 4 m
    away with material 0, and a 1.2 m one 2 m away with material 1, both centred on the
    view; one lamp lights both."""
    import base64

    pos = np.array([[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], np.float32)
    nrm = np.tile([0, 0, 1], (4, 1)).astype(np.float32)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: v = 0 at the top
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    blob = pos.tobytes() + nrm.tobytes() + uv.tobytes() + idx.tobytes()
    for i, img in enumerate(images):
        (tmp_path / f"img{i}.png").write_bytes(_png(img))
    prim = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 4.5}]}},
        "buffers": [
            {
                "byteLength": len(blob),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
            }
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": o, "byteLength": n}
            for o, n in [(0, 48), (48, 48), (96, 32), (128, 12)]
        ],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [-0.5, -0.5, 0],
                "max": [0.5, 0.5, 0],
            },
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
        "images": [{"uri": f"img{i}.png"} for i in range(len(images))],
        "textures": [{"source": i} for i in range(len(images))],
        "materials": materials,
        "meshes": [{"primitives": [{**prim, "material": m}]} for m in range(2)],
        "nodes": [
            {"mesh": 0, "translation": [0, 1.6, -4], "scale": [6, 6, 1]},
            {"mesh": 1, "translation": [0, 1.6, -2], "scale": [1.2, 1.2, 1]},
            {"translation": [0, 1.6, -0.5], "extensions": {"KHR_lights_punctual": {"light": 0}}},
        ],
        "scenes": [{"nodes": [0, 1, 2]}],
        "scene": 0,
    }
    path = tmp_path / "quads.gltf"
    path.write_text(json.dumps(doc))
    return path


RED_WALL = {"name": "red wall", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.05, 0.05, 1]}}


@pytest.mark.parametrize("path", PATHS)
def test_texture_transform_places_the_texture(host, path, tmp_path):
    """KHR_texture_transform (how Blender and others export a tiled or shifted texture): a
    red | blue texture shifted by half its width shows blue on the left, and tiled twice
    shows red again at the quarter; before, it was ignored with a warning."""
    pictures = {}
    for label, ext in (
        ("as authored", None),
        ("shifted", {"offset": [0.5, 0.0]}),
        ("tiled", {"scale": [2.0, 1.0]}),
    ):
        info: dict = {"index": 0}
        if ext is not None:
            info["extensions"] = {"KHR_texture_transform": ext}
        tiles = {
            "name": "tiles",
            "pbrMetallicRoughness": {"baseColorTexture": info, "metallicFactor": 0.0},
        }
        folder = tmp_path / label.replace(" ", "-")
        folder.mkdir()
        scene = load_scene(
            _two_quads_gltf(folder, [RED_WALL, tiles], [halves((230, 20, 20), (20, 20, 230))])
        )
        assert not any("transform" in w for w in scene.warnings), scene.warnings
        pictures[label] = draw(host, scene, **path)
    r, left = pixel_of(host, -0.45, 0.0, -2.0)  # near the pane's left edge
    _, quarter = pixel_of(host, -0.15, 0.0, -2.0)  # a quarter of the way from its centre
    authored, shifted, tiled = (pictures[k][r] for k in ("as authored", "shifted", "tiled"))
    assert authored[left, 0] > 2 * authored[left, 2]  # red on the left
    assert shifted[left, 2] > 2 * shifted[left, 0]  # shifted: blue on the left
    assert authored[quarter, 0] > 2 * authored[quarter, 2]  # the left half is red ...
    assert tiled[quarter, 2] > 2 * tiled[quarter, 0]  # ... tiled twice, blue at its quarter


@pytest.mark.parametrize("path", PATHS)
def test_transmissive_glass_shows_what_lies_behind(host, path, tmp_path):
    """Blender exports glass as an OPAQUE material with KHR_materials_transmission: drawn
    opaque, a window of it was a white pane that hid the garden and shut out the sun. It is
    blended glass now: the red wall shows through it, and it casts no shadow."""
    from app.sky_light import lets_light_through

    seen = {}
    for label, ext in (("plain", None), ("transmission", {"transmissionFactor": 1.0})):
        glass = {
            "name": "glass",
            "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "roughnessFactor": 0.0},
        }
        if ext is not None:
            glass["extensions"] = {"KHR_materials_transmission": ext}
        folder = tmp_path / label
        folder.mkdir()
        scene = load_scene(_two_quads_gltf(folder, [RED_WALL, glass], []))
        pane = next(
            i for i, m in enumerate(scene.meshes) if scene.materials[m.material].name == "glass"
        )
        seen[label] = (draw(host, scene, **path), bool(lets_light_through(scene)[pane]))
    r, c = pixel_of(host, 0.35, -0.35, -2.0)  # off the lamp's highlight in the pane
    (plain, plain_clear), (clear, clear_clear) = seen["plain"], seen["transmission"]
    assert plain[r, c, 1] > 0.5 * plain[r, c, 0]  # an opaque white pane
    assert clear[r, c, 0] > 2.5 * clear[r, c, 1]  # the red wall through the glass
    assert (plain_clear, clear_clear) == (False, True)  # no shadow, the sky's light through


def test_obj_colour_map_with_options_and_spaces_is_placed(host, tmp_path: Path):
    """Blender's OBJ exporter writes a tiled texture as ``map_Kd -s 2 2 1 file``; the whole
    rest of the line was taken as the file's name, so the floor lost its texture (and was
    said to be missing). Now the options are read: the texture is there and tiles twice
    (its red left half at the quarter, blue at the middle's left), and a name with a space
    is found."""
    (tmp_path / "wall.obj").write_text(
        "mtllib wall.mtl\n"
        "v -0.6 1.0 -2\nv 0.6 1.0 -2\nv 0.6 2.2 -2\nv -0.6 2.2 -2\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "usemtl tiles\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
    )
    (tmp_path / "wall.mtl").write_text(
        "newmtl tiles\nKd 1 1 1\nmap_Kd -s 2.000000 1.000000 1.000000 -bm 1 red blue.png\n"
    )
    Image.fromarray(halves((230, 20, 20), (20, 20, 230))).save(tmp_path / "red blue.png")
    scene = load_scene(tmp_path / "wall.obj", LoadOptions(unit_scale=1.0, split_edges_m=0.0))
    tiles = scene.materials[scene.meshes[0].material]
    assert tiles.texture is not None
    assert not any("missing" in w or "could not" in w for w in scene.warnings), scene.warnings
    assert scene.meshes[0].uvs[:, 0].max() == pytest.approx(2.0)
    img = draw(host, scene)
    r, c_red = pixel_of(host, -0.45, 0.0, -2.0)  # u 0.125 of the wall: 0.25 of the texture
    _, c_blue = pixel_of(host, -0.15, 0.0, -2.0)  # u 0.375: 0.75 of the texture
    assert img[r, c_red, 0] > 2 * img[r, c_red, 2], img[r, c_red]
    assert img[r, c_blue, 2] > 2 * img[r, c_blue, 0], img[r, c_blue]


def test_obj_colour_map_in_a_windows_subfolder_is_found(tmp_path: Path):
    """An MTL written on Windows names its textures with backslashes
    (``map_Kd textures\\oak floor.png``): the texture is found in the subfolder."""
    (tmp_path / "floor.obj").write_text(
        "mtllib floor.mtl\n"
        "v 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\n"
        "usemtl oak\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
    )
    (tmp_path / "floor.mtl").write_text("newmtl oak\nKd 1 1 1\nmap_Kd textures\\oak floor.png\n")
    (tmp_path / "textures").mkdir()
    Image.new("RGB", (4, 4), (150, 90, 40)).save(tmp_path / "textures" / "oak floor.png")
    scene = load_scene(tmp_path / "floor.obj", LoadOptions(unit_scale=1.0, split_edges_m=0.0))
    oak = scene.materials[scene.meshes[0].material]
    assert oak.texture is not None, scene.warnings
    assert tuple(scene.textures[oak.texture].rgba[0, 0, :3]) == (150, 90, 40)
    assert not any("missing" in w for w in scene.warnings), scene.warnings


@pytest.mark.parametrize("path", PATHS)
def test_an_unlit_material_shows_its_colour_whatever_the_lamps(host, path, tmp_path):
    """KHR_materials_unlit (a photo backdrop outside a window, a scanned room with its light
    in its textures) was shaded by the lamps as any surface. It shows its colour map's colours
    at the same level whatever the lamps give, where the lit wall behind follows them."""
    import dataclasses

    photo = halves((200, 150, 60), (60, 110, 200))
    unlit = {
        "name": "backdrop",
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
        "extensions": {"KHR_materials_unlit": {}},
    }
    scene = load_scene(_two_quads_gltf(tmp_path, [RED_WALL, unlit], [photo]))
    backdrop = next(m for m in scene.materials if m.name == "backdrop")
    assert backdrop.base_color[:3] == (0.0, 0.0, 0.0) and backdrop.emissive_texture is not None
    assert backdrop.unlit and not scene.materials[0].unlit
    shots = []
    for gain in (1.0, 20.0):
        lights = [dataclasses.replace(lt, intensity=lt.intensity * gain) for lt in scene.lights]
        shots.append(draw(host, dataclasses.replace(scene, lights=lights), **path))
    left, right = pixel_of(host, -0.3, 0.0, -2.0), pixel_of(host, 0.3, 0.0, -2.0)
    wall = pixel_of(host, 2.0, 0.0, -4.0)  # the lit red wall beside the backdrop
    dim, bright = shots
    assert bright[wall][0] > 3 * dim[wall][0]  # the lamps light the wall
    for img in shots:
        warm, cool = img[left], img[right]
        assert warm[0] > warm[1] > warm[2] and cool[2] > cool[1] > cool[0], (warm, cool)
        assert 40 < warm[0] < 250  # shown, neither black nor clipped
    assert np.abs(bright[left] - dim[left]).max() <= 2  # the lamps leave it as it is
    assert np.abs(bright[right] - dim[right]).max() <= 2


@pytest.mark.parametrize("path", PATHS)
def test_an_unlit_scan_shows_its_vertex_colours(host, path, tmp_path):
    """A scanned room exported unlit and coloured per vertex (KHR_materials_unlit with
    COLOR_0, no texture) showed as a flat white pane: the vertex colours multiplied the base
    colour, which an unlit material gives the lamps as black. Its colours show, as the glTF
    rule has it (base colour x its map x the vertex colours), and the Cycles job says so."""
    import dataclasses

    from app.lab.cycles_reference import material_for

    unlit = {"name": "scan", "extensions": {"KHR_materials_unlit": {}}}
    scene = load_scene(_two_quads_gltf(tmp_path, [RED_WALL, unlit], []))
    scan = next(i for i, m in enumerate(scene.materials) if m.name == "scan")
    meshes = [
        dataclasses.replace(m, colors=np.tile(np.float32([0.1, 0.25, 0.9]), (len(m.positions), 1)))
        if m.material == scan
        else m
        for m in scene.meshes
    ]
    img = draw(host, dataclasses.replace(scene, meshes=meshes), **path)
    r, g, b = (int(v) for v in img[pixel_of(host, 0.0, 0.0, -2.0)])
    assert b > 1.5 * g and g > 1.3 * r and b > 80, (r, g, b)  # before: (141, 141, 141)
    assert material_for(scene.materials[scan])["unlit"] is True
    assert "unlit" not in material_for(scene.materials[0])  # lit materials' jobs as before
