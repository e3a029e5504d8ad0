"""The first-run help: the essential keys over the view, until the user dismisses it.

A translucent child widget of the stereo view (Qt composes it over the GL picture; the rendered
image and screenshots of the framebuffer stay clean). It is shown on the first run only (the
preference ``help/overlay_seen``), F1 brings it back, and a click, Esc, a movement key or
"Got it" dismisses it; a movement key still moves.
"""

from __future__ import annotations

from PyQt6.QtCore import QEvent, QObject, Qt
from PyQt6.QtGui import QKeyEvent, QMouseEvent
from PyQt6.QtWidgets import QFrame, QGridLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from ui.gl_view import MOVE_KEYS, TURN_KEYS
from ui.prefs import prefs

SEEN_KEY = "help/overlay_seen"

ESSENTIAL_KEYS: tuple[tuple[str, str], ...] = (
    ("W A S D or arrows", "Walk, step sideways; Left / Right arrows turn"),
    ("Right-drag", "Look around"),
    ("Mouse", "Where you look (the gaze); hold the left button to fix it"),
    ("Tab", "Show or hide the panels (evaluation / normal mode)"),
    ("Ctrl+O", "Open a model, or pick one in the Samples menu"),
    ("F1", "This help again; Help > Controls lists every key"),
)


class KeysOverlay(QWidget):
    """Covers its parent (the view): a dark card of keys in the middle, the scene around it
    as it is (clicks anywhere on it dismiss it)."""

    def __init__(self, view: QWidget) -> None:
        super().__init__(view)
        self._view = view
        self.setAttribute(Qt.WidgetAttribute.WA_NoSystemBackground)
        self.setAutoFillBackground(False)
        card = QFrame(self)
        card.setObjectName("keys-card")
        card.setStyleSheet(
            "#keys-card { background: rgba(24, 26, 32, 225); border-radius: 10px; }"
            "QLabel { color: #f0f0f0; background: transparent; }"
            "QLabel[role='key'] { color: #ffd27a; font-weight: bold; }"
        )
        inner = QVBoxLayout(card)
        inner.setContentsMargins(22, 16, 22, 16)
        title = QLabel("Getting around")
        title.setStyleSheet("font-size: 15pt; font-weight: bold;")
        inner.addWidget(title)
        grid = QGridLayout()
        grid.setHorizontalSpacing(18)
        for row, (keys, what) in enumerate(ESSENTIAL_KEYS):
            k = QLabel(keys)
            k.setProperty("role", "key")
            grid.addWidget(k, row, 0)
            grid.addWidget(QLabel(what), row, 1)
        inner.addLayout(grid)
        self.button = QPushButton("Got it")
        self.button.setDefault(True)
        self.button.clicked.connect(self.dismiss)
        inner.addWidget(self.button, 0, Qt.AlignmentFlag.AlignRight)
        outer = QVBoxLayout(self)
        outer.addStretch(1)
        outer.addWidget(card, 0, Qt.AlignmentFlag.AlignHCenter)
        outer.addStretch(1)
        self.card = card
        view.installEventFilter(self)
        self.hide()

    # -- showing and dismissing ----------------------------------------------------------------
    def show_if_first_run(self) -> bool:
        """Show unless the user dismissed it before; returns whether it is shown."""
        if _truthy(prefs().value(SEEN_KEY, False)):
            return False
        self.open()
        return True

    def open(self) -> None:
        self.setGeometry(self._view.rect())
        self.show()
        self.raise_()

    def toggle(self) -> None:
        """F1: bring it back, or put it away."""
        if not self.isHidden():
            self.dismiss()
        else:
            self.open()

    def dismiss(self) -> None:
        """Hide it, remember that it was seen, and give the keyboard back to the view."""
        if self.isHidden():
            return
        self.hide()
        store = prefs()
        store.setValue(SEEN_KEY, True)
        store.sync()
        self._view.setFocus()

    # -- events ----------------------------------------------------------------------------------
    def eventFilter(self, obj: QObject, event: QEvent) -> bool:
        if obj is self._view and not self.isHidden():
            if event.type() == QEvent.Type.Resize:
                self.setGeometry(self._view.rect())
            elif event.type() == QEvent.Type.KeyPress and isinstance(event, QKeyEvent):
                if event.key() == Qt.Key.Key_Escape:
                    self.dismiss()
                    return True
                if event.key() in MOVE_KEYS or event.key() in TURN_KEYS:
                    self.dismiss()  # and the view walks: the key is not swallowed
        return False

    def keyPressEvent(self, event: QKeyEvent) -> None:
        key = event.key()
        if key == Qt.Key.Key_Escape or key in MOVE_KEYS or key in TURN_KEYS:
            self.dismiss()
            return
        super().keyPressEvent(event)

    def mousePressEvent(self, event: QMouseEvent) -> None:
        self.dismiss()
        event.accept()


def _truthy(value: object) -> bool:
    """QSettings' INI values come back as strings ('true') or as the type written."""
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1", "yes")
    return bool(value)
