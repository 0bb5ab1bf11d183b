"""Images out: EXR (float32 RGB through OpenEXR), PNG (exposure + sRGB), NPY (H x W x 3 float32)."""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np


def tonemap(image: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear RGB -> 8-bit sRGB after scaling by 2^exposure and clipping to [0, 1]."""
    x = np.clip(np.nan_to_num(image * (2.0**exposure), nan=0.0, posinf=1.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)


def _write_png(path: str, rgb8: np.ndarray):
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[r].tobytes() for r in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                 + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def save_image(path: str, image: np.ndarray, exposure: float = 0.0):
    """Write ``image`` (H x W x 3, linear) as .exr, .png or .npy, chosen by the extension."""
    image = np.asarray(image, dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must be H x W x 3, got shape {image.shape}")
    ext = os.path.splitext(path)[1].lower()
    if ext == ".exr":
        import OpenEXR

        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with OpenEXR.File(header, {"RGB": np.ascontiguousarray(image)}) as f:
            f.write(path)
    elif ext == ".png":
        _write_png(path, tonemap(image, exposure))
    elif ext == ".npy":
        np.save(path, image)
    else:
        raise ValueError(f"{path}: unknown image type {ext!r} (allowed: .exr, .png, .npy)")


def load_image(path: str) -> np.ndarray:
    """Read an .exr or .npy written by ``save_image`` back as H x W x 3 float32."""
    if path.lower().endswith(".exr"):
        import OpenEXR

        with OpenEXR.File(path) as f:
            return np.asarray(f.channels()["RGB"].pixels, dtype=np.float32)
    return np.load(path).astype(np.float32)
