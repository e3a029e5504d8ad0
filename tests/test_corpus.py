"""The bad-input corpus (tests/corpus.py) through ``vrpreview render``, and what some cases mean.

Every generated file must either load (exit 0, a PNG written; warnings allowed) or be refused
with one line naming the file (exit 2, stderr's last line ``vrpreview: error: ...``): never a
traceback, a crash, a hang, or fewer triangles than the undamaged file without a warning.
The corpus runs in-process in worker subprocesses (:func:`tests.corpus.run_corpus`); a few cases
also go through the real command line.

The ``test_gltf_rule_*`` tests state what the glTF reader must do with particular cases; the
reader that replaces trimesh's glTF path (issue 12) is meant to make them pass.
"""

from __future__ import annotations

import collections
import json
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from app.loaders import SceneLoadError
from app.scene import Scene
from app.trimesh_files import trimesh_load
from tests import corpus

TIMEOUT_S = 60.0
FAILURES = ("traceback", "crash", "hang", "bad-exit", "wrong-geometry")


@pytest.fixture(scope="module")
def cases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, corpus.Case]:
    built = corpus.build(tmp_path_factory.mktemp("corpus") / "files")
    return {c.name: c for c in built}


@pytest.fixture(scope="module")
def outcomes(
    cases: dict[str, corpus.Case], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[str, str]]:
    work = tmp_path_factory.mktemp("corpus-work")
    start = time.perf_counter()
    raw = corpus.run_corpus(list(cases.values()), work, TIMEOUT_S, workers=2)
    seconds = time.perf_counter() - start
    result = {name: corpus.classify(case, raw[name]) for name, case in cases.items()}
    counts = collections.Counter(o for o, _ in result.values())
    (work / "outcomes.json").write_text(json.dumps(result, indent=1))
    print(f"\ncorpus: {len(cases)} files in {seconds:.0f} s: {dict(counts)} ({work})")
    return result


def _table(outcomes: dict[str, tuple[str, str]], cases: dict[str, corpus.Case], family: str):
    bad = [
        f"  {o}: {name}: {detail[:300]}"
        for name, (o, detail) in outcomes.items()
        if cases[name].family == family and o in FAILURES
    ]
    return bad


def test_corpus_is_big_and_named(cases: dict[str, corpus.Case]) -> None:
    assert len(cases) >= 300
    categories = collections.Counter(c.category for c in cases.values())
    for needed in ("glb-truncated", "glb-flipped", "gltf-type", "gltf-uri", "image", "obj", "ply"):
        assert categories[needed] > 0, needed
    assert all(c.path.is_file() for c in cases.values())


def test_corpus_obj_ply_load_or_refuse_cleanly(
    outcomes: dict[str, tuple[str, str]], cases: dict[str, corpus.Case]
) -> None:
    bad = _table(outcomes, cases, "objply")
    assert not bad, "OBJ/PLY files that neither loaded nor were refused cleanly:\n" + "\n".join(bad)


def test_corpus_gltf_load_or_refuse_cleanly(
    outcomes: dict[str, tuple[str, str]], cases: dict[str, corpus.Case]
) -> None:
    bad = _table(outcomes, cases, "gltf")
    assert not bad, "glTF/GLB files that neither loaded nor were refused cleanly:\n" + "\n".join(
        bad
    )


def test_corpus_valid_files_load(outcomes: dict[str, tuple[str, str]]) -> None:
    for name in ("valid-box", "obj-valid", "ply-ascii-valid", "ply-binary-valid"):
        assert outcomes[name][0] == "loaded", (name, outcomes[name])


def test_runner_names_the_file_that_crashed_or_hung(
    cases: dict[str, corpus.Case], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The harness itself: a crash or a hang is pinned on its file, and the rest still run."""
    names = ["generic-obj-empty", "generic-ply-empty", "generic-gltf-null", "generic-glb-empty"]
    faults = {names[1]: "crash", names[2]: "hang"}
    monkeypatch.setenv("VRPREVIEW_CORPUS_FAULTS", json.dumps(faults))
    picked = [cases[n] for n in names]
    raw = corpus.run_corpus(picked, tmp_path, timeout_s=8.0)
    got = {c.name: corpus.classify(c, raw[c.name])[0] for c in picked}
    assert got == {
        names[0]: "refused",
        names[1]: "crash",
        names[2]: "hang",
        names[3]: "refused",
    }


# ------------------------------------------------------------------------------------------
# a few through the real command line
# ------------------------------------------------------------------------------------------

END_TO_END = {
    "valid-box": "loaded",
    "generic-glb-garbage": "refused",
    "glb-truncated-at01030": "refused",
    "obj-vertex-one-number": "loaded",
    "name-obj-latin1": "loaded",  # a file name whose bytes are Latin-1, through argv
    "ply-binary-2e31-vertices": "refused",
}


@pytest.mark.parametrize("name", sorted(END_TO_END))
def test_command_line_end_to_end(name: str, cases: dict[str, corpus.Case], tmp_path: Path) -> None:
    case = cases[name]
    out = tmp_path / "x.png"
    proc = subprocess.run(
        [sys.executable, "-m", "ui.launcher", "render", "--scene", str(case.path)]
        + ["--out", str(out), "--size", corpus.SIZE],
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
        env=corpus.worker_env(),
        cwd=tmp_path,
    )
    assert proc.returncode >= 0, f"killed by signal {-proc.returncode}"
    res = {"rc": proc.returncode, "stderr": proc.stderr, "png": out.is_file()}
    if proc.returncode == 0:
        res["tris"] = corpus.read_scene(case.path).triangle_count
    outcome, detail = corpus.classify(case, res)
    assert outcome == END_TO_END[name], (outcome, detail, proc.stderr[-2000:])


# ------------------------------------------------------------------------------------------
# OBJ and PLY: what the repairs do
# ------------------------------------------------------------------------------------------


def _tris(scene: Scene) -> np.ndarray:
    return np.concatenate([m.positions[m.indices.reshape(-1, 3)] for m in scene.meshes])


def _refused(path: Path, *words: str) -> str:
    with pytest.raises(SceneLoadError) as err:
        corpus.read_scene(path)
    msg = str(err.value)
    assert path.name in msg and "unexpected" not in msg, msg
    for w in words:
        assert w in msg, msg
    return msg


def test_obj_short_vertex_line_keeps_the_indices(cases: dict[str, corpus.Case]) -> None:
    path = cases["obj-vertex-one-number"].path  # 'v 1' is vertex 2; the faces use 1, 3, 4, 5
    notes: list[str] = []
    trimesh_load(path, warnings=notes)
    assert any("fewer than 3 coordinates" in n and "line 2" in n for n in notes), notes
    scene = corpus.read_scene(path)
    assert scene.triangle_count == 2
    # the two triangles share the edge from vertex 1 to vertex 3 and stand at right angles
    tris = _tris(scene)
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    assert abs(float(normals[0] @ normals[1])) < 1e-5


def test_obj_face_using_the_short_vertex_is_dropped(tmp_path: Path) -> None:
    path = tmp_path / "short.obj"
    path.write_text("v 0 0 0\nv 1\nv 1 0 0\nv 0 1 0\nf 1 3 4\nf 2 3 4\n")
    scene = corpus.read_scene(path)
    assert scene.triangle_count == 1
    assert any("dropped" in w for w in scene.warnings), scene.warnings


@pytest.mark.parametrize(
    "name, tris",
    [
        ("obj-face-missing-vertex", 1),
        ("obj-face-huge-index", 1),
        ("obj-face-huge-index-64bit", 1),
        ("obj-face-negative-too-far", 1),
    ],
)
def test_obj_faces_past_the_vertices_are_dropped(
    name: str, tris: int, cases: dict[str, corpus.Case]
) -> None:
    notes: list[str] = []
    trimesh_load(cases[name].path, warnings=notes)
    assert any("dropped 1 face" in n for n in notes), notes
    assert corpus.read_scene(cases[name].path).triangle_count == tris


def test_obj_uv_index_past_the_end_keeps_the_face(cases: dict[str, corpus.Case]) -> None:
    notes: list[str] = []
    trimesh_load(cases["obj-face-uv-missing"].path, warnings=notes)
    assert corpus.read_scene(cases["obj-face-uv-missing"].path).triangle_count == 1


@pytest.mark.parametrize(
    "name",
    [
        "obj-latin1-comment",
        "obj-cp1252-quotes",
        "ply-latin1-comment-ascii",
        "ply-latin1-comment-binary",
        "name-obj-latin1",
        "name-ply-latin1",
    ],
)
def test_latin1_text_loads(name: str, cases: dict[str, corpus.Case]) -> None:
    scene = corpus.read_scene(cases[name].path)
    assert scene.triangle_count == cases[name].base_tris


@pytest.mark.parametrize("name", ["obj-latin1-mtl-utf8-names", "obj-latin1-mtl-latin1-names"])
def test_latin1_obj_keeps_its_mtl_and_texture(name: str, cases: dict[str, corpus.Case]) -> None:
    """A Windows export: the OBJ and MTL in cp1252, the MTL and texture names accented."""
    scene = corpus.read_scene(cases[name].path)
    assert scene.triangle_count == 1
    mat = scene.materials[scene.meshes[0].material]
    assert mat.texture is not None, (mat, scene.warnings)
    assert mat.name.startswith("peinture_"), mat.name


def test_obj_in_utf16_and_with_old_mac_line_ends_loads(cases: dict[str, corpus.Case]) -> None:
    assert corpus.read_scene(cases["obj-utf16"].path).triangle_count == 1
    assert corpus.read_scene(cases["obj-cr-only"].path).triangle_count == 1


@pytest.mark.parametrize("name", ["ply-wrong-byte-order-le-data", "ply-wrong-byte-order-be-data"])
def test_ply_in_the_wrong_byte_order_is_read_the_other_way(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    notes: list[str] = []
    trimesh_load(cases[name].path, warnings=notes)
    assert any("byte order" in n for n in notes), notes
    scene = corpus.read_scene(cases[name].path)
    assert scene.triangle_count == 2
    tris = _tris(scene)
    assert np.ptp(tris.reshape(-1, 3), axis=0).max() == pytest.approx(1.0, rel=1e-5)


@pytest.mark.parametrize(
    "name", ["ply-face-index-out-of-range", "ply-face-index-negative", "ply-face-index-huge-binary"]
)
def test_ply_faces_past_the_vertices_are_dropped(name: str, cases: dict[str, corpus.Case]) -> None:
    notes: list[str] = []
    trimesh_load(cases[name].path, warnings=notes)
    assert any("dropped 1 face" in n for n in notes), notes
    assert corpus.read_scene(cases[name].path).triangle_count == 1


@pytest.mark.parametrize(
    "name, words",
    [
        ("ply-ascii-count-too-high", ("40 vertices", "counts are wrong")),
        ("ply-ascii-count-too-low", ("3 vertices", "counts are wrong")),
        ("ply-ascii-face-count-too-high", ("20 faces",)),
        ("ply-ascii-2e31-vertices", ("2147483648 vertices",)),
        ("ply-binary-2e31-vertices", ("2147483648 vertices", "truncated")),
        ("ply-binary-2e31-faces", ("2147483648 faces",)),
        ("ply-binary-2e62-vertices", ("vertices",)),
        ("ply-ascii-count-negative", ("negative",)),
        ("ply-unknown-format", ("binary_middle_endian",)),
        ("ply-unknown-property-type", ("quad",)),
        ("ply-no-end-header", ("end_header",)),
    ],
)
def test_ply_with_impossible_counts_is_refused_before_reading(
    name: str, words: tuple[str, ...], cases: dict[str, corpus.Case]
) -> None:
    tracemalloc.start()
    start = time.perf_counter()
    try:
        _refused(cases[name].path, *words)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert time.perf_counter() - start < 5.0
    assert peak < 64 * 2**20, f"{peak / 2**20:.0f} MB allocated"


def test_ply_over_the_memory_limit_is_refused(tmp_path: Path) -> None:
    n = 100_000
    rng = np.random.default_rng(3)
    header = (
        f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n"
        "property float x\nproperty float y\nproperty float z\nend_header\n"
    ).encode()
    path = tmp_path / "cloud.ply"
    path.write_bytes(header + rng.random((n, 3), dtype=np.float32).tobytes())
    with pytest.raises(SceneLoadError, match="over the 1 MB limit") as err:
        trimesh_load(path, max_memory_mb=1)
    assert "cloud.ply" in str(err.value) and "max_memory_mb" in str(err.value)
    trimesh_load(path, max_memory_mb=8192)  # the same file under the default limit


def test_obj_over_the_memory_limit_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "big.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n" * 20_000 + "f 1 2 3\n")
    with pytest.raises(SceneLoadError, match="over the 1 MB limit"):
        trimesh_load(path, max_memory_mb=1)


# ------------------------------------------------------------------------------------------
# glTF rules (for the new glTF reader; several fail with trimesh's)
# ------------------------------------------------------------------------------------------


def _loaded(case: corpus.Case) -> Scene:
    scene = corpus.read_scene(case.path)
    return scene


def _height(scene: Scene) -> float:
    pts = np.concatenate([m.positions for m in scene.meshes])
    return float(np.ptp(pts[:, 1]))


def test_gltf_rule_percent_encoded_uris_are_decoded(cases: dict[str, corpus.Case]) -> None:
    """``Box%20.bin`` is the file ``Box .bin`` (URIs are percent-encoded)."""
    scene = _loaded(cases["gltf-uri-percent-encoded"])
    assert scene.triangle_count == corpus.BOX_TRIS
    assert scene.materials[scene.meshes[0].material].texture is not None, scene.warnings
    assert _loaded(cases["gltf-uri-unicode-name"]).triangle_count == corpus.BOX_TRIS


@pytest.mark.parametrize("mode", ["strip", "fan"])
def test_gltf_rule_strips_and_fans_are_triangulated(
    mode: str, cases: dict[str, corpus.Case]
) -> None:
    assert _loaded(cases[f"gltf-mode-{mode}"]).triangle_count == 4
    assert _loaded(cases[f"gltf-mode-{mode}-as-triangles"]).triangle_count == 2


def test_gltf_rule_sparse_accessors_are_applied(cases: dict[str, corpus.Case]) -> None:
    """Sparse values raise vertices 0 and 1 by 1.5 m: the box grows from 1 m to 2.5 m tall."""
    scene = _loaded(cases["gltf-sparse-valid"])
    assert scene.triangle_count == corpus.BOX_TRIS
    assert _height(scene) == pytest.approx(2.5 * _height(_loaded(cases["valid-box"])), rel=1e-4)


@pytest.mark.parametrize("name", ["gltf-sparse-index-past-end", "gltf-sparse-count-huge"])
def test_gltf_rule_bad_sparse_is_refused_or_warned(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    try:
        scene = _loaded(cases[name])
    except SceneLoadError as exc:
        assert cases[name].path.name in str(exc) and "unexpected" not in str(exc)
        return
    assert any("sparse" in w.lower() for w in scene.warnings), scene.warnings


@pytest.mark.parametrize(
    "name, words",
    [
        ("gltf-ext-draco-garbage-data", ("Draco",)),
        ("gltf-ext-required-unknown", ("EXT_made_up",)),
        ("gltf-ext-required-basisu", ("KHR_texture_basisu",)),
        ("gltf-ext-min-version-2-1", ("2.1",)),
    ],
)
def test_gltf_rule_required_extensions_we_lack_are_refused(
    name: str, words: tuple[str, ...], cases: dict[str, corpus.Case]
) -> None:
    _refused(cases[name].path, *words)


@pytest.mark.parametrize(
    "name",
    [
        "gltf-ext-required-draco",  # declared required, read by DracoPy
        "gltf-ext-draco-with-fallback",  # the Draco data is broken: the plain accessors serve
        "gltf-ext-meshopt-with-fallback",
        "gltf-ext-required-meshopt",  # declared required, read by meshoptimizer
        "gltf-ext-used-unknown",
        "gltf-ext-required-quantization",
        "gltf-ext-required-transform",
        "gltf-ext-min-version-2-0",
    ],
)
def test_gltf_rule_optional_or_supported_extensions_load(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    assert _loaded(cases[name]).triangle_count == corpus.BOX_TRIS


@pytest.mark.parametrize(
    "name",
    [
        "gltf-count-accessors-1-count-0",
        "gltf-range-meshes-0-primitives-0-attributes-POSITION-0",
        "gltf-structure-attributes-empty",
        "gltf-data-uri-buffer-bad-chars",
        "gltf-data-uri-buffer-empty",
        "gltf-structure-json-bom",
        "gltf-structure-node-cycle",
        "gltf-structure-node-self-child",
        "gltf-type-materials-0-pbrMetallicRoughness-baseColorTexture-str",
        "gltf-type-materials-0-pbrMetallicRoughness-baseColorTexture-neg",
    ],
)
def test_gltf_rule_broken_structure_is_refused_in_words_or_repaired_with_a_warning(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    """Refused naming the problem (not 'an unexpected X' or a bare Python exception text), or,
    where something can be cut away (a node cycle, a broken texture reference), loaded with a
    warning that says what was dropped."""
    try:
        scene = _loaded(cases[name])
    except SceneLoadError as exc:
        msg = str(exc)
        assert cases[name].path.name in msg
        for raw in ("unexpected", "AssertionError", "'POSITION')", "BOM (decode"):
            assert raw not in msg, msg
        return
    if name.endswith("json-bom"):
        return  # a BOM is skipped: nothing was wrong with the model
    words = ("cycle", "loop") if "node" in name else ("texture",)
    assert any(any(w in note.lower() for w in words) for note in scene.warnings), scene.warnings


def test_gltf_rule_deep_extras_are_refused_in_one_line(cases: dict[str, corpus.Case]) -> None:
    """A 10,000-deep ``extras`` is no exported model (Python's JSON parser stops at ~1,000
    levels): refused in words, never a RecursionError traceback."""
    for name in ("gltf-structure-extras-nested-10000", "gltf-structure-node-extras-nested-10000"):
        _refused(cases[name].path, "nested too deeply")


def test_gltf_rule_deep_node_chains_load(cases: dict[str, corpus.Case]) -> None:
    assert _loaded(cases["gltf-structure-node-chain-10000"]).triangle_count == corpus.BOX_TRIS


@pytest.mark.parametrize(
    "name", ["gltf-range-index-values-past-end", "gltf-range-index-values-huge"]
)
def test_gltf_rule_indices_past_the_vertices_are_dropped_with_a_warning(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    scene = _loaded(cases[name])
    assert scene.triangle_count == corpus.BOX_TRIS - 1
    assert any("drop" in w for w in scene.warnings), scene.warnings


@pytest.mark.parametrize("name", ["image-png-16bit", "image-png-palette", "image-png-1x1"])
def test_gltf_rule_unusual_images_become_textures(name: str, cases: dict[str, corpus.Case]) -> None:
    scene = _loaded(cases[name])
    assert scene.materials[scene.meshes[0].material].texture is not None, scene.warnings


@pytest.mark.parametrize(
    "name",
    ["image-png-header-bomb-100000", "image-jpeg-header-bomb-65500", "image-png-zlib-bomb-6000"],
)
def test_gltf_rule_image_bombs_are_not_decoded_at_full_size(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    scene = _loaded(cases[name])
    assert scene.triangle_count == corpus.BOX_TRIS
    for tex in scene.textures:
        assert max(tex.rgba.shape[:2]) <= 8192


@pytest.mark.parametrize(
    "name",
    [
        "gltf-uri-buffer-etc-passwd",
        "gltf-uri-buffer-file-url",
        "gltf-uri-buffer-http",
        "gltf-uri-buffer-dotdot-deep",
        "gltf-uri-buffer-dev-zero",
    ],
)
def test_gltf_rule_hostile_buffer_uris_are_refused(
    name: str, cases: dict[str, corpus.Case]
) -> None:
    _refused(cases[name].path)
