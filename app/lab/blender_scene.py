"""The Cycles side of ``vrpreview reference``: a job folder in, linear radiance out.

Run as a script in its own process (``python blender_scene.py JOB_DIR``) so that Blender's
800 MB, its threads and its log stay out of the caller; it imports only ``bpy`` and numpy,
nothing of this project. :mod:`app.lab.cycles_reference` writes the job:

- ``job.json``: camera, lights, materials, world and render options (see ``write_job`` there);
- ``meshes.npz``: every mesh merged into one (positions, normals, uvs, colours, triangle
  indices, a material index per triangle), in our axes (Y up, metres);
- ``tex_N.png``: the textures as authored (sRGB).

and this script writes ``radiance.npy``: (H, W, 3) float32 linear luminance in cd/m2 (our
renderer's unit, see the conversions in :mod:`app.lab.cycles_reference`), row 0 at the top.

Axes: ours are Y up, -Z forward; Blender's Z up, so a point (x, y, z) goes to (x, -z, y).
"""

from __future__ import annotations

import importlib
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

#: Bounces a full light path may make (diffuse, glossy, transmission each): enough that what a
#: white room's walls would still pass on after them is below a sample's noise (0.85^64).
FULL_BOUNCES = 64


def to_blender(v: np.ndarray) -> np.ndarray:
    """Our Y-up (x, y, z) as Blender's Z-up (x, -z, y), for points and directions."""
    v = np.asarray(v, np.float64)
    return np.stack([v[..., 0], -v[..., 2], v[..., 1]], axis=-1)


def _matrix(right: np.ndarray, up: np.ndarray, back: np.ndarray, location: np.ndarray):
    """An object matrix whose local X, Y, Z axes are ``right``, ``up``, ``back`` (Blender
    axes): a camera or a lamp looks down its local -Z."""
    m = importlib.import_module("mathutils").Matrix.Identity(4)
    for row in range(3):
        m[row][0], m[row][1], m[row][2], m[row][3] = (
            right[row],
            up[row],
            back[row],
            location[row],
        )
    return m


def _aim(direction: np.ndarray, location: np.ndarray):
    """A lamp's matrix shining along ``direction`` (Blender axes)."""
    d = np.asarray(direction, np.float64)
    d = d / max(float(np.linalg.norm(d)), 1e-12)
    helper = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    right = np.cross(d, helper)
    right /= np.linalg.norm(right)
    up = np.cross(right, d)
    return _matrix(right, up, -d, location)


def build_mesh(bpy, arrays, job: dict):
    """One Blender mesh of every triangle, a material slot per material of ours."""
    pos = to_blender(arrays["positions"]).astype(np.float32)
    nrm = to_blender(arrays["normals"]).astype(np.float32)
    tris = arrays["indices"].astype(np.int32)
    n_tri = tris.shape[0]
    me = bpy.data.meshes.new("scene")
    me.vertices.add(pos.shape[0])
    me.vertices.foreach_set("co", pos.ravel())
    me.loops.add(n_tri * 3)
    me.loops.foreach_set("vertex_index", tris.ravel())
    me.polygons.add(n_tri)
    me.polygons.foreach_set("loop_start", np.arange(0, n_tri * 3, 3, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(n_tri, 3, np.int32))
    me.polygons.foreach_set("material_index", arrays["material"].astype(np.int32))
    me.polygons.foreach_set("use_smooth", np.ones(n_tri, bool))
    uv = arrays["uvs"].astype(np.float32)[tris.ravel()]
    uv[:, 1] = 1.0 - uv[:, 1]  # ours: v = 0 is the image's top row; Blender's: its bottom
    layer = me.uv_layers.new(name="uv")
    layer.data.foreach_set("uv", uv.ravel())
    colors = np.concatenate(
        [arrays["colors"].astype(np.float32), np.ones((pos.shape[0], 1), np.float32)], axis=1
    )
    attr = me.color_attributes.new("col", "FLOAT_COLOR", "POINT")
    attr.data.foreach_set("color", colors.ravel())
    me.update()
    me.normals_split_custom_set_from_vertices(nrm.tolist())
    for mat in job["materials"]:
        me.materials.append(build_material(bpy, mat, job))
    ob = bpy.data.objects.new("scene", me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def _image(bpy, job: dict, index: int, data: bool):
    """Texture ``index`` as a Blender image: sRGB colour, or linear data (normal and
    metallic-roughness maps), one image per texture and colour space."""
    cache = job.setdefault("_images", {})
    key = (index, data)
    if key not in cache:
        # a new datablock per load (check_existing off): a texture used both ways gets two
        image = bpy.data.images.load(str(Path(job["dir"]) / f"tex_{index}.png"))
        image.colorspace_settings.name = "Non-Color" if data else "sRGB"
        cache[key] = image
    return cache[key]


def _texture_node(bpy, tree, job: dict, index: int, data: bool = False):
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, job, index, data)
    tex.interpolation = "Linear"
    tex.extension = "REPEAT" if job["textures"][index]["repeat"] else "EXTEND"
    return tex


def _multiply(tree, a, b):
    node = tree.nodes.new("ShaderNodeMix")
    node.data_type = "RGBA"
    node.blend_type = "MULTIPLY"
    node.inputs["Factor"].default_value = 1.0
    tree.links.new(a, node.inputs["A"])
    if isinstance(b, tuple):
        node.inputs["B"].default_value = b
    else:
        tree.links.new(b, node.inputs["B"])
    return node.outputs["Result"]


def _scaled(tree, value, factor: float):
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = "MULTIPLY"
    tree.links.new(value, node.inputs[0])
    node.inputs[1].default_value = float(factor)
    return node.outputs["Value"]


def build_material(bpy, m: dict, job: dict):
    """Principled BSDF with glTF's meaning: base colour x texture (sRGB) x vertex colour;
    roughness and metallic times the metallic-roughness map's G and B; a tangent-space normal
    map (uv map "uv", glTF's +Y up, Blender's too) at ``normal_scale``; emission in cd/m2
    (strength 1) times the emissive map; alpha from the base colour (x the texture's alpha),
    cut at ``alpha_cutoff`` for MASK, opaque for OPAQUE."""
    mat = bpy.data.materials.new(m["name"] or "material")
    mat.use_nodes = True  # (deprecated in Blender 5, where it is on already)
    tree = mat.node_tree
    bsdf = tree.nodes["Principled BSDF"]
    base = m["base_color"]
    vc = tree.nodes.new("ShaderNodeVertexColor")
    vc.layer_name = "col"
    colour = _multiply(tree, vc.outputs["Color"], (base[0], base[1], base[2], 1.0))
    alpha = None
    if m["texture"] is not None:
        tex = _texture_node(bpy, tree, job, m["texture"])
        colour = _multiply(tree, colour, tex.outputs["Color"])
        alpha = _scaled(tree, tex.outputs["Alpha"], base[3])
    tree.links.new(colour, bsdf.inputs["Base Color"])
    mr = m.get("metallic_roughness_texture")
    if mr is not None:
        tex = _texture_node(bpy, tree, job, mr, data=True)
        split = tree.nodes.new("ShaderNodeSeparateColor")
        tree.links.new(tex.outputs["Color"], split.inputs["Color"])
        tree.links.new(
            _scaled(tree, split.outputs["Green"], m["roughness"]), bsdf.inputs["Roughness"]
        )
        tree.links.new(_scaled(tree, split.outputs["Blue"], m["metallic"]), bsdf.inputs["Metallic"])
    else:
        bsdf.inputs["Roughness"].default_value = float(m["roughness"])
        bsdf.inputs["Metallic"].default_value = float(m["metallic"])
    nt = m.get("normal_texture")
    if nt is not None:
        tex = _texture_node(bpy, tree, job, nt, data=True)
        normal = tree.nodes.new("ShaderNodeNormalMap")
        normal.space = "TANGENT"
        normal.uv_map = "uv"
        normal.inputs["Strength"].default_value = float(m.get("normal_scale", 1.0))
        tree.links.new(tex.outputs["Color"], normal.inputs["Color"])
        tree.links.new(normal.outputs["Normal"], bsdf.inputs["Normal"])
    mode = m.get("alpha_mode", "OPAQUE")
    if mode == "OPAQUE":
        bsdf.inputs["Alpha"].default_value = 1.0
    elif alpha is None:
        bsdf.inputs["Alpha"].default_value = float(base[3])
    elif mode == "MASK":
        cut = tree.nodes.new("ShaderNodeMath")
        cut.operation = "GREATER_THAN"
        tree.links.new(alpha, cut.inputs[0])
        cut.inputs[1].default_value = float(m.get("alpha_cutoff", 0.5))
        tree.links.new(cut.outputs["Value"], bsdf.inputs["Alpha"])
    else:
        tree.links.new(alpha, bsdf.inputs["Alpha"])
    emissive = m["emissive"]
    if max(emissive) > 0.0:
        glow = (*emissive, 1.0)
        et = m.get("emissive_texture")
        emit = None
        if et is not None:
            tex = _texture_node(bpy, tree, job, et)
            emit = _multiply(tree, tex.outputs["Color"], glow)
        if m.get("unlit"):  # KHR_materials_unlit: the vertex colours tint it, as ours
            emit = _multiply(tree, vc.outputs["Color"], glow if emit is None else emit)
        if emit is not None:
            tree.links.new(emit, bsdf.inputs["Emission Color"])
        else:
            bsdf.inputs["Emission Color"].default_value = glow
        bsdf.inputs["Emission Strength"].default_value = 1.0
    if m.get("shadowless"):
        _let_light_through(tree, bsdf, sky=bool(job.get("sky")))
    return mat


def _let_light_through(tree, bsdf, sky: bool) -> None:
    """A surface that casts no shadow in our renderer (render/shadows.py ``casts``: a glowing
    pane showing the sky, a lamp's shade or bulb): shadow rays pass it, so lamps shine through
    their shades; with daylight on, every ray but the camera's (the sky beyond the pane lights
    the room through it, and the pane is what the camera sees, as in our frame)."""
    path = tree.nodes.new("ShaderNodeLightPath")
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    mix = tree.nodes.new("ShaderNodeMixShader")
    if sky:
        tree.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
        tree.links.new(clear.outputs["BSDF"], mix.inputs[1])
        tree.links.new(bsdf.outputs["BSDF"], mix.inputs[2])
    else:
        tree.links.new(path.outputs["Is Shadow Ray"], mix.inputs["Fac"])
        tree.links.new(bsdf.outputs["BSDF"], mix.inputs[1])
        tree.links.new(clear.outputs["BSDF"], mix.inputs[2])
    out = tree.nodes["Material Output"]
    tree.links.new(mix.outputs["Shader"], out.inputs["Surface"])


def build_lights(bpy, job: dict) -> None:
    for i, light in enumerate(job["lights"]):
        kind = light["kind"]
        if kind == "directional":
            data = bpy.data.lights.new(f"sun{i}", "SUN")
            data.energy = light["sun_strength"]
            data.angle = math.radians(2.0 * 0.266)  # the sun's disc (app.sky_model)
            shine = to_blender(np.asarray(light["direction"]))
            location = np.zeros(3)
        else:
            data = bpy.data.lights.new(f"lamp{i}", "SPOT" if kind == "spot" else "POINT")
            data.energy = light["watts"]
            data.shadow_soft_size = 0.0  # ours are points
            if kind == "spot":
                outer = math.radians(light["outer_cone_deg"])
                data.spot_size = min(2.0 * outer, math.pi)
                inner = math.radians(light["inner_cone_deg"])
                data.spot_blend = max(0.0, min(1.0, 1.0 - inner / max(outer, 1e-6)))
            shine = to_blender(np.asarray(light["direction"]))
            location = to_blender(np.asarray(light["position"]))
        data.color = light["color"]
        ob = bpy.data.objects.new(data.name, data)
        ob.matrix_world = _aim(shine, location)
        bpy.context.scene.collection.objects.link(ob)


def build_world(bpy, job: dict, arrays) -> None:
    world = bpy.data.worlds.new("world")
    world.use_nodes = True  # off on a new world, even in Blender 5.0
    bpy.context.scene.world = world
    background = world.node_tree.nodes["Background"]
    sky = job.get("sky")
    if not sky:
        background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        return
    # Our own sky (app/lab/cycles_reference.py sky_image), already in the Environment
    # Texture's layout: Blender's rows run bottom-up, so the image goes in flipped.
    sky_rgb = np.asarray(arrays[sky["image"]], np.float32)
    height, width = sky_rgb.shape[:2]
    image = bpy.data.images.new("sky", width, height, alpha=False, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"  # linear cd/m2 as they are
    rgba = np.concatenate([sky_rgb, np.ones((height, width, 1), np.float32)], axis=2)
    image.pixels.foreach_set(np.ascontiguousarray(np.flipud(rgba)).ravel())
    image.update()
    node = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    node.image = image
    node.interpolation = "Linear"
    node.projection = "EQUIRECTANGULAR"
    world.node_tree.links.new(node.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = float(sky["strength"])


def build_camera(bpy, job: dict) -> None:
    c = job["camera"]
    cam = bpy.data.cameras.new("eye")
    cam.sensor_fit = "VERTICAL"
    cam.sensor_height = 24.0
    cam.lens = cam.sensor_height / 2.0 / math.tan(math.radians(c["fov_y_deg"]) / 2.0)
    width, height = job["size"]
    # Our off-axis frustum's centre in NDC ((r + l) / (r - l)) as Blender's shift, which is
    # in units of the larger image side.
    cam.shift_x = c["ndc_shift_x"] * width / (2.0 * max(width, height))
    cam.shift_y = c["ndc_shift_y"] * height / (2.0 * max(width, height))
    cam.clip_start = c["near"]
    cam.clip_end = c["far"]
    ob = bpy.data.objects.new("eye", cam)
    ob.matrix_world = _matrix(
        to_blender(np.asarray(c["right"])),
        to_blender(np.asarray(c["up"])),
        -to_blender(np.asarray(c["forward"])),
        to_blender(np.asarray(c["position"])),
    )
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.scene.camera = ob


def render(job_dir: Path) -> None:
    # Imported by name: PyInstaller must not pull Blender (821 MB) into the app's bundle.
    bpy = importlib.import_module("bpy")

    start = time.perf_counter()
    job = json.loads((job_dir / "job.json").read_text())
    job["dir"] = str(job_dir)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    with np.load(job_dir / "meshes.npz") as arrays:
        if arrays["indices"].shape[0]:
            build_mesh(bpy, arrays, job)
        build_world(bpy, job, arrays)
    build_lights(bpy, job)
    build_camera(bpy, job)
    width, height = job["size"]
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.film_transparent = False
    r.threads_mode = "FIXED" if job.get("threads") else "AUTO"
    if job.get("threads"):
        r.threads = int(job["threads"])
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = int(job["samples"])
    cy.use_adaptive_sampling = False
    cy.seed = 0
    cy.use_denoising = bool(job.get("denoise", True))
    cy.denoiser = "OPENIMAGEDENOISE"
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0  # no clamp: the indirect light keeps its energy
    cy.caustics_reflective = cy.caustics_refractive = False
    # The light's whole path: Blender's own defaults stop a path after 4 diffuse and 4 glossy
    # bounces, which in a white room (walls of reflectance 0.8-0.9) leaves out a quarter of
    # the light bounced (0.8^4 of it); the renderer's even light sums 48 bounces. Cycles'
    # Russian roulette ends the paths that carry little long before FULL_BOUNCES.
    # ``max_bounces`` 0: the direct light alone (transparent shadows still pass panes).
    bounces = job.get("max_bounces")
    if bounces is None:
        bounces = FULL_BOUNCES
    cy.max_bounces = int(bounces)
    cy.diffuse_bounces = cy.glossy_bounces = cy.transmission_bounces = int(bounces)
    cy.volume_bounces = int(bounces)
    # Linear radiance out: no view transform, no look, no film exposure.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.color_management = "OVERRIDE"
    r.image_settings.linear_colorspace_settings.name = "Linear Rec.709"
    exr = job_dir / "radiance.exr"
    r.filepath = str(exr)
    built = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    rendered = time.perf_counter()
    image = bpy.data.images.load(str(exr))
    image.colorspace_settings.name = "Non-Color"
    px = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(px)
    radiance = np.flipud(px.reshape(height, width, 4)[:, :, :3]).copy()
    np.save(job_dir / "radiance.npy", radiance)
    (job_dir / "timing.json").write_text(
        json.dumps(
            {
                "build_s": built - start,
                "render_s": rendered - built,
                "bpy": bpy.app.version_string,
            }
        )
    )


if __name__ == "__main__":
    render(Path(sys.argv[1]))
