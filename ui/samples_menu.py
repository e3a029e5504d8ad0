"""The Samples menu: the built-in scenes, then the models of the shared scenes folder.

The folder is ``VRPREVIEW_SCENES`` or ``../shared/scenes`` (see :func:`app.scenes.samples_folder`);
its models are grouped by their first subfolder and named from their file names. Without the
folder the menu lists the built-in scenes only.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import groupby

from PyQt6.QtGui import QAction
from PyQt6.QtWidgets import QMenu, QWidget

from app import scenes


def fill_samples_menu(menu: QMenu, owner: QWidget, load: Callable[[str], None]) -> list[QAction]:
    """Add one entry per sample to ``menu``; each loads its scene. Returns the actions."""
    added: list[QAction] = []

    def add(target: QMenu, text: str, name: str, tip: str) -> None:
        a = QAction(text, owner)
        a.setToolTip(tip)
        a.setStatusTip(tip)
        a.setData(name)
        a.triggered.connect(lambda _=False, n=name: load(n))
        target.addAction(a)
        added.append(a)

    built_in = menu.addSection("Built-in scenes")
    built_in.setText("Built-in scenes")
    for name in scenes.BUILTIN:
        add(menu, scenes.BUILTIN_LABELS.get(name, scenes.plain_name(name)), name, name)
    folder = scenes.samples_folder()
    found = scenes.find_samples(folder)
    if found:
        menu.addSection("Models in the scenes folder")
        for group, items in groupby(found, key=lambda s: s.group):
            members = list(items)
            if not group or (len(members) == 1 and members[0].label == group):
                target = menu  # a folder holding one model: no submenu of one entry
            else:
                target = menu.addMenu(group)
            for s in members:
                add(target, s.label, str(s.path), str(s.path))
    return added
