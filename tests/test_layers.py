"""app/ and render/ must run headless: no Qt import anywhere below ui/."""

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_no_qt_imports_below_ui():
    offenders = []
    for package in ("app", "render", "assets"):
        for path in (ROOT / package).rglob("*.py"):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            for node in ast.walk(tree):
                names = (
                    [a.name for a in node.names]
                    if isinstance(node, ast.Import)
                    else [node.module or ""]
                    if isinstance(node, ast.ImportFrom)
                    else []
                )
                if any(n.split(".")[0] in ("PyQt6", "PySide6", "qtpy", "ui") for n in names):
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not offenders, f"Qt/ui imported below ui/: {offenders}"


def test_headless_modules_import_without_qt():
    code = (
        "import sys, ui.launcher, app.lab.cli, app.lab.bench, app.session, render.offscreen, "
        "render.renderer; "
        "assert not any(m.startswith('PyQt6') for m in sys.modules), 'Qt was imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
