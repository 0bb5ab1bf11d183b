"""Images out: EXR (float32 RGB through OpenEXR), PNG (exposure + sRGB), NPY (H x W x 3 float32)."""

from __future__ import annotations

import os
import struct
import tempfile
import zlib

import numpy as np


def tonemap(image: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Linear RGB -> 8-bit sRGB after scaling by 2^exposure and clipping to [0, 1]."""
    x = np.clip(np.nan_to_num(image * (2.0**exposure), nan=0.0, posinf=1.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(srgb * 255.0).astype(np.uint8)


def png_bytes(rgb8: np.ndarray) -> bytes:
    """An H x W x 3 uint8 image as PNG file bytes."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[r].tobytes() for r in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def _write_png(path: str, rgb8: np.ndarray):
    with open(path, "wb") as fh:
        fh.write(png_bytes(rgb8))


IMAGE_TYPES = (".exr", ".png", ".npy")


def _image_type(path: str) -> str:
    ext = os.path.splitext(path)[1].lower()
    if ext not in IMAGE_TYPES:
        raise ValueError(f"{path}: unknown image type {ext!r} (allowed: {', '.join(IMAGE_TYPES)})")
    return ext


def check_output_path(path: str) -> None:
    """Raise ``ValueError`` naming ``path`` unless an image can be written there: a known
    extension, not a folder, in an existing folder this process can create files in."""
    path = os.fspath(path)
    allowed = "a file path ending in " + ", ".join(IMAGE_TYPES) + " in an existing, writable folder"
    if os.path.isdir(path):
        raise ValueError(f"{path}: is a folder (allowed: {allowed})")
    _image_type(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        above = folder
        while not os.path.exists(above):
            above = os.path.dirname(above)
        problem = f"{above} is a file, not a folder" if not os.path.isdir(above) else f"folder {folder} does not exist"
        raise ValueError(f"{path}: {problem} (allowed: {allowed})")
    try:  # the real test: os.access says yes to root on a read-only file system
        fd, probe = tempfile.mkstemp(prefix=".warpvol-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ValueError(f"{path}: cannot write in folder {folder}: {exc.strerror} (allowed: {allowed})") from None


def _write_npy(path: str, image: np.ndarray):
    with open(path, "wb") as fh:
        np.save(fh, image)


def _write_exr(path: str, image: np.ndarray):
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": np.ascontiguousarray(image)}) as f:
        f.write(path)


def save_image(path: str, image: np.ndarray, exposure: float = 0.0):
    """Write ``image`` (H x W x 3, linear) as .exr, .png or .npy, chosen by the extension.

    The file is written beside the target under a temporary name and renamed onto it, so an
    interrupted write leaves the previous file (or none), never a truncated one.
    """
    path = os.fspath(path)
    image = np.asarray(image, dtype=np.float32)
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must be H x W x 3, got shape {image.shape}")
    if not np.isfinite(exposure):
        raise ValueError(f"exposure {exposure!r} is not finite (allowed: a finite number of stops)")
    ext = _image_type(path)
    folder, name = os.path.split(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=ext, dir=folder)
    os.close(fd)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the image the usual mode
        if ext == ".exr":
            _write_exr(tmp, image)
        elif ext == ".png":
            _write_png(tmp, tonemap(image, exposure))
        else:
            _write_npy(tmp, image)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def load_image(path: str) -> np.ndarray:
    """Read an .exr or .npy written by ``save_image`` back as H x W x 3 float32."""
    if path.lower().endswith(".exr"):
        import OpenEXR

        with OpenEXR.File(path) as f:
            return np.asarray(f.channels()["RGB"].pixels, dtype=np.float32)
    return np.load(path).astype(np.float32)
