"""Minimal PFM reader/writer (numpy only). Arrays are [rows top-to-bottom, cols, channels]."""
import numpy as np


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        if kind not in (b"PF", b"Pf"):
            raise ValueError(f"{path}: not a PFM (header {kind!r})")
        dims = f.readline().split()
        while not dims:  # tolerate blank/comment-free extra lines
            dims = f.readline().split()
        w, h = int(dims[0]), int(dims[1])
        scale = float(f.readline().strip())
        dtype = "<f4" if scale < 0 else ">f4"
        c = 3 if kind == b"PF" else 1
        data = np.frombuffer(f.read(w * h * c * 4), dtype=dtype)
    img = data.reshape(h, w, c).astype(np.float32)
    return img[::-1].copy()  # PFM rows are bottom to top


def write_pfm(path, img):
    """img: [H, W, 3] (or [H, W]) float, row 0 at the top. Writes little-endian, rows bottom-up."""
    img = np.asarray(img, dtype=np.float32)
    if img.ndim == 2:
        img = img[:, :, None]
    h, w, c = img.shape
    if c not in (1, 3):
        raise ValueError(f"PFM needs 1 or 3 channels, got {c}")
    with open(path, "wb") as f:
        f.write(b"PF\n" if c == 3 else b"Pf\n")
        f.write(f"{w} {h}\n-1.0\n".encode())
        f.write(np.ascontiguousarray(img[::-1]).astype("<f4").tobytes())
