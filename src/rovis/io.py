"""Small file helpers: outputs are written whole or not at all."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any


def publish(tmp: str | os.PathLike[str], path: str | os.PathLike[str]) -> None:
    """Give a finished temporary file the usual permissions (mkstemp makes it 0600) and
    rename it into place atomically."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, path)


def write_figure_atomic(fig: Any, path: str | os.PathLike[str]) -> Path:
    """Save a matplotlib figure as PNG via a temporary file and a rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".png", dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, format="png")
        publish(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` via a temporary file in the same folder and a rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        publish(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def write_image_atomic(path: str | os.PathLike[str], image: object) -> Path:
    """Write an image (format from the suffix, e.g. ``.png``) via a temporary file and a rename.

    Raises
    ------
    OSError
        When OpenCV cannot encode the image in that format.
    """
    import cv2
    import numpy as np

    path = Path(path)
    ok, buf = cv2.imencode(path.suffix or ".png", np.asarray(image))
    if not ok:
        raise OSError(f"{path}: could not encode the image")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(buf.tobytes())
        publish(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


class LinesWriter:
    """A text file written line by line into a temporary file and renamed into place on
    :meth:`close` (or leaving a ``with`` block, also on an exception or Ctrl-C), so the file
    at ``path`` is never half-written: it holds every line written before the close.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, self._tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", dir=self.path.parent)
        self._fh = os.fdopen(fd, "w", encoding="utf-8")
        self.lines = 0

    def write(self, line: str) -> None:
        """Append one line (a newline is added)."""
        self._fh.write(line.rstrip("\n") + "\n")
        self._fh.flush()
        self.lines += 1

    def close(self) -> Path:
        if not self._fh.closed:
            self._fh.close()
            try:
                publish(self._tmp, self.path)
            finally:
                if os.path.exists(self._tmp):
                    os.unlink(self._tmp)
        return self.path

    def __enter__(self) -> LinesWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
