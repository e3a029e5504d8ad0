"""Help > Controls: every key of the window, in one table.

The menu commands come from the window's own QActions (text and shortcut), so a command added
later with a shortcut is listed without touching this file; the keys the stereo view handles
itself (walking, looking, the gaze) are :data:`VIEW_KEYS`, kept beside ``ui.gl_view``'s key maps.
"""

from __future__ import annotations

from PyQt6.QtGui import QAction, QKeySequence
from PyQt6.QtWidgets import (
    QAbstractItemView,
    QDialog,
    QDialogButtonBox,
    QHeaderView,
    QLabel,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

# What ui.gl_view.StereoView does with keys and the mouse (MOVE_KEYS, TURN_KEYS, the mouse
# handlers) and the window's Tab filter.
VIEW_KEYS: tuple[tuple[str, str], ...] = (
    ("W or Up arrow", "Walk forward"),
    ("S or Down arrow", "Walk back"),
    ("A / D", "Step left / right"),
    ("Left / Right arrow", "Turn left / right"),
    ("E / Q", "Rise / sink (in fly mode: Settings tab, navigation, fly)"),
    ("Right- or middle-drag", "Look around (turn, look up and down)"),
    ("Mouse over the view", "Where you look (the gaze point, the same in both eyes)"),
    ("Hold the left button", "Fix the gaze where it is (the gaze counts as held)"),
    ("Tab (in the view)", "Switch between evaluation mode (panels) and normal mode (scene only)"),
    ("Esc", "Close the first-run help"),
)


def action_text(action: QAction) -> str:
    """A menu entry as a sentence: no '&' mnemonics, no tab-separated hint, no '…'."""
    text = action.text().split("\t", 1)[0]
    text = text.replace("&&", "\0").replace("&", "").replace("\0", "&")
    return text.rstrip("…").rstrip(".").strip()


def action_keys(window: QWidget) -> list[tuple[str, str]]:
    """(shortcut, what it does) for every QAction of ``window`` that has a shortcut."""
    rows: list[tuple[str, str]] = []
    seen: set[int] = set()
    for action in [*window.actions(), *window.findChildren(QAction)]:
        if id(action) in seen:
            continue
        seen.add(id(action))
        keys = [s for s in action.shortcuts() if not s.isEmpty()]
        if not keys:
            continue
        shortcut = " or ".join(k.toString(QKeySequence.SequenceFormat.NativeText) for k in keys)
        rows.append((shortcut, action_text(action)))
    return sorted(set(rows), key=_key_order)


def _key_order(row: tuple[str, str]) -> tuple:
    """Function keys first in number order (F3 before F11), then single keys, then chords."""
    key = row[0]
    if key[:1] == "F" and key[1:].isdigit():
        return (0, int(key[1:]), key)
    return (1 if len(key) <= 3 else 2, 0, key)


class ControlsDialog(QDialog):
    """Two tables: the view's own keys and mouse, then the commands with shortcuts."""

    def __init__(self, window: QWidget) -> None:
        super().__init__(window)
        self.setWindowTitle("Controls")
        layout = QVBoxLayout(self)
        self.view_table = _table(VIEW_KEYS)
        self.command_table = _table(action_keys(window))
        layout.addWidget(QLabel("<b>In the view</b> (click the view first)"))
        layout.addWidget(self.view_table)
        layout.addWidget(QLabel("<b>Commands</b> (also in the menus)"))
        layout.addWidget(self.command_table)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)
        self.resize(720, 760)

    def rows(self) -> list[tuple[str, str]]:
        """Everything listed, view keys first (what a user reads)."""
        out = []
        for table in (self.view_table, self.command_table):
            for r in range(table.rowCount()):
                key, what = table.item(r, 0), table.item(r, 1)
                out.append((key.text() if key else "", what.text() if what else ""))
        return out


def _table(rows) -> QTableWidget:
    table = QTableWidget(len(rows), 2)
    table.setHorizontalHeaderLabels(["Keys", "What it does"])
    table.verticalHeader().setVisible(False)
    table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
    table.setSelectionMode(QAbstractItemView.SelectionMode.NoSelection)
    for r, (key, what) in enumerate(rows):
        table.setItem(r, 0, QTableWidgetItem(key))
        table.setItem(r, 1, QTableWidgetItem(what))
    header = table.horizontalHeader()
    header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
    header.setStretchLastSection(True)
    table.setWordWrap(True)
    table.resizeRowsToContents()
    # Tall enough for every row: a list of keys is read at a glance, not scrolled.
    table.setMinimumHeight(min(520, header.height() + table.verticalHeader().length() + 4))
    return table
