"""What a designer installs: the wheel in a fresh venv, the one-folder app, the desktop entry.

The wheel is built from a copy of the sources, installed into a new venv that sees the already
installed dependencies through a ``.pth`` file (nothing is downloaded), and its ``vrpreview``
renders from an empty folder in a clean environment: the picture must equal the checkout's.
The PyInstaller bundle gets the same check (``make dist-check`` runs it by hand).
"""

from __future__ import annotations

import configparser
import importlib.util
import shutil
import site
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from app.lab import cli
from app.loaders import SUPPORTED_EXTENSIONS

ROOT = Path(__file__).resolve().parent.parent
PACKAGING = ROOT / "packaging"
PACKAGES = ("app", "ui", "render", "assets")
SIZE = "64x64"


def _load(name: str):
    """A script of packaging/ as a module (packaging/ is no package)."""
    spec = importlib.util.spec_from_file_location(name, PACKAGING / f"{name}.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


dist_check = _load("dist_check")


def tree_files(pattern: str) -> set[str]:
    """Files of the four packages matching ``pattern``, as paths relative to the checkout."""
    return {
        p.relative_to(ROOT).as_posix()
        for pkg in PACKAGES
        for p in (ROOT / pkg).rglob(pattern)
        if "__pycache__" not in p.parts
    }


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel, built the way ``make dist`` does from a clean copy of the sources."""
    src = tmp_path_factory.mktemp("src")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for pkg in PACKAGES:
        shutil.copytree(ROOT / pkg, src / pkg, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out), str(src)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (whl,) = out.glob("vrpreview-*.whl")
    return whl


def test_the_wheel_carries_every_module_shader_and_asset(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    shaders = tree_files("*.glsl")
    assert len(shaders) >= 20 and shaders <= names, sorted(shaders - names)
    modules = tree_files("*.py")
    assert modules <= names, sorted(modules - names)
    data = tree_files("*.json") | tree_files("*.png")
    assert "assets/paths/showroom_walkthrough.json" in data
    assert "assets/icons/vrpreview-256.png" in data
    assert data <= names, sorted(data - names)
    assert not any(n.startswith(("tests/", "packaging/")) for n in names)
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    assert "vrpreview = ui.launcher:main" in zipfile.ZipFile(wheel).read(entry_points).decode()


def test_the_wheel_in_a_fresh_venv_renders_the_showroom_headless(wheel, tmp_path):
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    # The dependencies this interpreter already has, without downloading them again.
    target = Path(
        subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    (target / "dependencies.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    proc = subprocess.run(
        # --ignore-installed: the checkout's own editable install is visible through the .pth
        [sys.executable, "-m", "pip", "--python", str(python), "install", "-q"]
        + ["--no-deps", "--no-index", "--ignore-installed", str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr

    # The installed copy is the one that runs, not this checkout.
    where = subprocess.run(
        [str(python), "-c", "import render.shaders, ui.launcher; print(render.shaders.__file__)"],
        cwd=tmp_path,
        env=dist_check.clean_env(tmp_path),
        capture_output=True,
        text=True,
    )
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(target)

    picture, _seconds, output = dist_check.render_outside(
        str(env_dir / "bin" / "vrpreview"), SIZE, tmp_path / "run"
    )
    assert "wrote x.png" in output
    assert picture.shape == (64, 64, 3)
    assert picture.std() > 10, "the render is blank"
    in_tree = dist_check.render_in_tree(SIZE)
    assert np.abs(picture.astype(int) - in_tree.astype(int)).mean() < dist_check.MAX_MEAN_DIFF


def test_the_one_folder_app_renders_with_no_python_and_no_checkout(tmp_path):
    """``make dist``'s PyInstaller bundle, built from packaging/vrpreview.spec (about 1 min)."""
    proc = subprocess.run(
        [sys.executable, "-m", "PyInstaller", "--noconfirm", "--log-level", "WARN"]
        + ["--distpath", str(tmp_path / "dist"), "--workpath", str(tmp_path / "build")]
        + [str(PACKAGING / "vrpreview.spec")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    bundle = tmp_path / "dist" / "vrpreview"
    try:
        check_bundle(bundle, tmp_path)
    finally:  # 400 MB: not kept in pytest's last three temporary folders
        shutil.rmtree(tmp_path / "dist")
        shutil.rmtree(tmp_path / "build")


def check_bundle(bundle: Path, tmp_path: Path) -> None:
    assert (bundle / "vrpreview").is_file()
    assert not (bundle / "_internal" / "tests").exists()
    qt_plugins = bundle / "_internal" / "PyQt6" / "Qt6" / "plugins"
    assert (qt_plugins / "platforms" / "libqxcb.so").is_file()  # the window on X11
    shaders = list((bundle / "_internal" / "render" / "shaders").glob("*.glsl"))
    assert len(shaders) == len(tree_files("*.glsl"))
    # meshoptimizer's binding loads its library with ctypes from its own folder (app/lod.py)
    assert list((bundle / "_internal" / "meshoptimizer").glob("_meshoptimizer*.so"))

    # As root (CI, this machine) every Python install and the checkout are hidden from it.
    picture, _seconds, output = dist_check.render_outside(
        str(bundle / "vrpreview"), SIZE, tmp_path / "run", isolate=dist_check.can_isolate()
    )
    assert "embree unavailable" not in output  # the fast ray caster travelled with it
    assert "could not be simplified" not in output  # and meshoptimizer's library (ctypes)
    assert picture.shape == (64, 64, 3) and picture.std() > 10
    in_tree = dist_check.render_in_tree(SIZE)
    assert np.abs(picture.astype(int) - in_tree.astype(int)).mean() < dist_check.MAX_MEAN_DIFF

    # Bad input from the bundle is the same clear message as from the checkout.
    bad = subprocess.run(
        [str(bundle / "vrpreview"), "render", "--scene", "nowhere.glb", "--out", "x.png"],
        cwd=tmp_path,
        env=dist_check.clean_env(tmp_path),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode == cli.EXIT_USAGE
    assert "vrpreview: error:" in bad.stderr and "nowhere.glb" in bad.stderr


# -- the desktop entry ---------------------------------------------------------------------------

# The shared-mime-info names of the formats the loaders read (PLY's is ours: vrpreview-mime.xml).
MIME_OF = {
    ".glb": "model/gltf-binary",
    ".gltf": "model/gltf+json",
    ".obj": "model/obj",
    ".ply": "application/x-ply",
}


def desktop_entry(text: str) -> configparser.SectionProxy:
    parser = configparser.ConfigParser(interpolation=None)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read_string(text)
    return parser["Desktop Entry"]


def test_desktop_entry_opens_every_model_format_the_app_reads():
    entry = desktop_entry((PACKAGING / "vrpreview.desktop").read_text())
    assert entry["Type"] == "Application" and entry["Name"] == "VR Preview"
    assert entry["Exec"] == "vrpreview %f"
    assert entry["Icon"] == "vrpreview"
    types = [t for t in entry["MimeType"].split(";") if t]
    assert sorted(types) == sorted(MIME_OF[ext] for ext in SUPPORTED_EXTENSIONS)
    mime = (PACKAGING / "vrpreview-mime.xml").read_text()
    assert '<mime-type type="application/x-ply">' in mime and '<glob pattern="*.ply"/>' in mime


def test_install_desktop_puts_entry_icons_and_file_type_in_the_data_home(tmp_path):
    install = _load("install_desktop")
    bundle = str(tmp_path / "vrpreview" / "vrpreview")
    assert install.main(["--data-home", str(tmp_path), "--exec", bundle, "--no-refresh"]) == 0
    entry = desktop_entry((tmp_path / "applications" / "vrpreview.desktop").read_text())
    assert entry["Exec"] == f"{bundle} %f" and entry["TryExec"] == bundle
    assert entry["Icon"] == "vrpreview"
    for size in (48, 128, 256):
        icon = Image.open(tmp_path / "icons" / "hicolor" / f"{size}x{size}" / "apps/vrpreview.png")
        assert icon.size == (size, size) and icon.mode == "RGBA"
    assert (tmp_path / "mime" / "packages" / "vrpreview.xml").read_text() == (
        PACKAGING / "vrpreview-mime.xml"
    ).read_text()


def test_the_committed_icons_are_the_drawing(tmp_path):
    make_icon = _load("make_icon")
    assert make_icon.main(["--out", str(tmp_path)]) == 0
    for size in make_icon.SIZES:
        drawn = np.asarray(Image.open(tmp_path / f"vrpreview-{size}.png"), dtype=int)
        committed = np.asarray(Image.open(ROOT / "assets/icons" / f"vrpreview-{size}.png"))
        assert committed.shape == (size, size, 4)
        assert np.abs(drawn - committed).mean() < 1.0
        alpha = committed[..., 3]
        assert alpha[0, 0] == 0 and alpha[size // 2, size // 2] == 255  # a tile, round corners
        # Two lenses: the room's warm colours left and right of the middle, the tile between.
        row = committed[size // 2, :, :3].astype(int)
        warm = (row[:, 0] > row[:, 2] + 40).nonzero()[0]
        assert warm.min() < size * 0.45 and warm.max() > size * 0.55


# -- `vrpreview FILE`, as the desktop entry runs it ----------------------------------------------


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["room.glb"], ["--scene", "room.glb"]),
        (["/models/Room One.gltf"], ["--scene", "/models/Room One.gltf"]),
        (["--set", "stereo.ipd_mm=60", "a.obj"], ["--set", "stereo.ipd_mm=60", "--scene", "a.obj"]),
        (["render", "--scene", "x.ply", "--out", "y.png"], None),
        (["--scene", "corridor"], None),
        (["rendr"], None),
    ],
)
def test_a_file_argument_is_the_scene(argv, expected):
    assert cli.file_as_scene(argv, cli.build_parser()) == (argv if expected is None else expected)


def test_vrpreview_file_passes_the_file_to_the_window(tmp_path, monkeypatch):
    model = tmp_path / "crate.glb"
    model.write_bytes(b"glTF")
    monkeypatch.setenv("DISPLAY", ":0")
    opened = []
    code = cli.main([str(model)], lambda scene, settings, path: opened.append(scene) or 0)
    assert code == 0 and opened == [str(model)]


def test_a_mistyped_command_names_the_commands(capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["rendr"], lambda *_: 0)
    assert exit_info.value.code == cli.EXIT_USAGE
    assert "invalid choice: 'rendr'" in capsys.readouterr().err


def test_vrpreview_file_opens_the_model_in_the_real_window(qapp, tmp_path, monkeypatch):
    import trimesh
    from PyQt6.QtWidgets import QApplication

    from ui import launcher
    from ui.main_window import MainWindow

    model = tmp_path / "crate.glb"
    trimesh.creation.box(extents=(1.0, 0.5, 0.8)).export(model)
    seen: dict[str, object] = {}

    def exec_once(_app) -> int:  # instead of the event loop: look at the window, close it
        # The window main() opened (earlier tests may leave closed windows not yet deleted).
        (window,) = [
            w
            for w in QApplication.topLevelWidgets()
            if isinstance(w, MainWindow) and not any(w is b for b in before)
        ]
        window.wait_for_load()
        seen["title"] = window.windowTitle()
        seen["triangles"] = window.session.scene.triangle_count
        window.close()
        window.deleteLater()
        return 0

    monkeypatch.setattr(QApplication, "exec", exec_once)
    before = list(QApplication.topLevelWidgets())  # held: no id is reused
    assert launcher.main([str(model)]) == 0
    from app.loaders import load_scene

    # The crate's 12 triangles as the loader gives them (its long edges split for the light).
    expected = load_scene(model).triangle_count
    assert expected >= 12
    assert seen == {"title": "VR Preview — crate", "triangles": expected}
