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


#: A 5 x 7 bitmap font (rows top to bottom, 5 bits each, the high bit leftmost) for captions
#: burned into images: upper-case letters (lower case is drawn in upper case), digits and a few signs.
FONT = {
    "A": (14, 17, 17, 31, 17, 17, 17), "B": (30, 17, 17, 30, 17, 17, 30), "C": (14, 17, 16, 16, 16, 17, 14),
    "D": (30, 17, 17, 17, 17, 17, 30), "E": (31, 16, 16, 30, 16, 16, 31), "F": (31, 16, 16, 30, 16, 16, 16),
    "G": (14, 17, 16, 23, 17, 17, 15), "H": (17, 17, 17, 31, 17, 17, 17), "I": (14, 4, 4, 4, 4, 4, 14),
    "J": (7, 2, 2, 2, 2, 18, 12), "K": (17, 18, 20, 24, 20, 18, 17), "L": (16, 16, 16, 16, 16, 16, 31),
    "M": (17, 27, 21, 21, 17, 17, 17), "N": (17, 17, 25, 21, 19, 17, 17), "O": (14, 17, 17, 17, 17, 17, 14),
    "P": (30, 17, 17, 30, 16, 16, 16), "Q": (14, 17, 17, 17, 21, 18, 13), "R": (30, 17, 17, 30, 20, 18, 17),
    "S": (15, 16, 16, 14, 1, 1, 30), "T": (31, 4, 4, 4, 4, 4, 4), "U": (17, 17, 17, 17, 17, 17, 14),
    "V": (17, 17, 17, 17, 17, 10, 4), "W": (17, 17, 17, 21, 21, 21, 10), "X": (17, 17, 10, 4, 10, 17, 17),
    "Y": (17, 17, 17, 10, 4, 4, 4), "Z": (31, 1, 2, 4, 8, 16, 31),
    "0": (14, 17, 19, 21, 25, 17, 14), "1": (4, 12, 4, 4, 4, 4, 14), "2": (14, 17, 1, 2, 4, 8, 31),
    "3": (31, 2, 4, 2, 1, 17, 14), "4": (2, 6, 10, 18, 31, 2, 2), "5": (31, 16, 30, 1, 1, 17, 14),
    "6": (6, 8, 16, 30, 17, 17, 14), "7": (31, 1, 2, 4, 8, 8, 8), "8": (14, 17, 17, 14, 17, 17, 14),
    "9": (14, 17, 17, 15, 1, 2, 12),
    " ": (0,) * 7, ".": (0, 0, 0, 0, 0, 12, 12), ",": (0, 0, 0, 0, 12, 4, 8), ":": (0, 12, 12, 0, 12, 12, 0),
    "-": (0, 0, 0, 31, 0, 0, 0), "_": (0, 0, 0, 0, 0, 0, 31), "%": (24, 25, 2, 4, 8, 19, 3),
    "=": (0, 0, 31, 0, 31, 0, 0), "(": (2, 4, 8, 8, 8, 4, 2), ")": (8, 4, 2, 2, 2, 4, 8),
    "/": (0, 1, 2, 4, 8, 16, 0), "+": (0, 4, 4, 31, 4, 4, 0), "?": (14, 17, 1, 2, 4, 0, 4),
}


def text_mask(lines: list[str], width: int, scale: int = 1) -> np.ndarray:
    """Lines of text as a (7 s + 2 s) * len(lines) + 2 s by ``width`` float32 mask (1 where ink),
    in ``FONT`` at ``scale`` s pixels a font pixel, each character 6 s wide, from 2 s in; what passes
    the width is cut, a character not in the font is drawn as "?"."""
    s = max(1, int(scale))
    mask = np.zeros((9 * s * len(lines) + 2 * s, width), np.float32)
    for i, line in enumerate(lines):
        for j, ch in enumerate(line.upper()):
            x0, y0 = 2 * s + 6 * s * j, 2 * s + 9 * s * i
            if x0 + 5 * s > width:
                break
            rows = np.array(FONT.get(ch, FONT["?"]))
            bits = ((rows[:, None] >> np.arange(4, -1, -1)[None, :]) & 1).astype(np.float32)
            mask[y0 : y0 + 7 * s, x0 : x0 + 5 * s] = np.kron(bits, np.ones((s, s), np.float32))
    return mask


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
