"""Image files the commands write: OpenEXR channels and PNG previews."""
from __future__ import annotations

import numpy as np

__all__ = ["write_exr", "save_png"]


def write_exr(path, channels: dict) -> None:
    """An OpenEXR file (ZIP-compressed scanlines) of float32 ``channels`` (name -> 2D)."""
    import OpenEXR

    data = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, data) as f:
        f.write(str(path))


def save_png(path, rgb) -> None:
    """An 8-bit RGB PNG of ``rgb`` (rows, cols, 3), floats in [0, 1]."""
    from PIL import Image

    Image.fromarray(np.round(rgb * 255).astype(np.uint8), mode="RGB").save(path)
