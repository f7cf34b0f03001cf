"""Reading camera images: one loader that every stage uses, so every stage sees the same gray.

Camera files come as 8-bit gray, 8-bit colour (BGR/BGRA) or 16-bit (machine-vision PNG/TIFF);
the pipeline works on 8-bit gray, so the conversion happens here, once.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray


def to_gray_u8(image: NDArray[np.generic], name: str = "image") -> NDArray[np.uint8]:
    """Convert an image array to 8-bit gray.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3|4), uint8, uint16 or float
        Gray, BGR or BGRA (OpenCV order). 16-bit images are scaled by 1/257 (full range kept);
        float images are taken as [0, 1] when their maximum is ≤ 1, else as [0, 255].
    name : str
        Used in error messages.

    Returns
    -------
    ndarray, shape (H, W), uint8

    Raises
    ------
    ValueError
        For an empty image or an unsupported number of channels.
    """
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.size == 0:
        raise ValueError(f"{name}: empty image (shape {img.shape})")
    if img.ndim not in (2, 3):
        raise ValueError(f"{name}: expected an (H, W) or (H, W, 3|4) image, got shape {img.shape}")
    if img.ndim == 3:
        if img.shape[2] not in (3, 4):
            raise ValueError(f"{name}: expected 1, 3 or 4 channels, got {img.shape[2]}")
        if img.dtype not in (np.uint8, np.uint16, np.float32):
            img = img.astype(np.float32)
        code = cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        img = cv2.cvtColor(img, code)
    if img.dtype == np.uint8:
        return np.ascontiguousarray(img)
    if img.dtype == np.uint16:
        # 65535 / 257 = 255 exactly, so the full 16-bit range maps onto the full 8-bit range.
        return np.clip(np.rint(img / 257.0), 0, 255).astype(np.uint8)
    if img.dtype == np.bool_:
        return img.astype(np.uint8) * 255
    f = img.astype(np.float64)
    if not np.all(np.isfinite(f)):
        raise ValueError(f"{name}: contains NaN or infinity")
    scale = 255.0 if f.max(initial=0.0) <= 1.0 else 1.0
    return np.clip(np.rint(f * scale), 0, 255).astype(np.uint8)


def read_gray(path: str | os.PathLike[str]) -> NDArray[np.uint8]:
    """Read an image file as 8-bit gray.

    Parameters
    ----------
    path : path-like
        Any format OpenCV reads (PNG, JPEG, TIFF, PGM, …), 8 or 16 bits, gray or colour.

    Returns
    -------
    ndarray, shape (H, W), uint8

    Raises
    ------
    ValueError
        Naming the file when it does not exist or cannot be decoded.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: image file not found")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError(f"{path}: cannot read image (not an image file, or a format OpenCV "
                         "does not decode)")
    return to_gray_u8(img, str(path))
