"""Camera images: raw 8-bit frame files, PNG/JPEG images, and PNG files written whole."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tourbot.errors import InputError
from tourbot.io.output import output_file

__all__ = [
    "read_camera_images",
    "read_gray_image",
    "read_image_stream",
    "read_raw_frames",
    "write_image_stream",
    "write_png",
]


def read_raw_frames(path: str | Path, width: int, height: int) -> NDArray[np.uint8]:
    """Frames ``(N, height, width)`` of a headerless 8-bit grayscale stream (``.gz`` or plain)."""
    p = Path(path)
    try:
        if p.suffix == ".gz":
            with gzip.open(p) as fh:
                raw = fh.read()
        else:
            raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read the frames: {exc.strerror or exc}", path=p) from exc
    size = width * height
    if len(raw) == 0 or len(raw) % size:
        raise InputError(
            f"{len(raw)} bytes is not a whole number of {width}x{height} frames", path=p, field="size"
        )
    return np.frombuffer(raw, dtype=np.uint8).reshape(-1, height, width)


def read_gray_image(path: str | Path) -> NDArray[np.uint8]:
    """An image file as 8-bit grayscale (colour images are converted); one clear error if unreadable."""
    import cv2

    p = Path(path)
    if not p.is_file():
        raise InputError("no such image file", path=p)
    img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError("not an image OpenCV can read (PNG, JPEG, ...)", path=p, field="image")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY)
    if img.dtype != np.uint8:
        raise InputError(f"expected an 8-bit image, got {img.dtype}", path=p, field="image.depth")
    return np.asarray(img)


def write_png(path: str | Path, image: NDArray[np.uint8]) -> None:
    """An image written whole as PNG (through a temporary file)."""
    import cv2

    with output_file(path) as tmp:
        ok, buf = cv2.imencode(".png", image)
        if not ok:
            raise InputError("could not encode the image as PNG", path=path)
        tmp.write_bytes(buf.tobytes())


def write_image_stream(path: str | Path, times: list[float], images: list[NDArray[np.uint8]]) -> None:
    """A sidecar image stream: timestamps and 8-bit images in one compressed ``.npz``, written whole."""
    if len(times) != len(images):
        raise ValueError("write_image_stream needs one timestamp per image")
    stack = np.stack(images) if images else np.zeros((0, 0, 0), dtype=np.uint8)
    with output_file(path) as tmp, tmp.open("wb") as fh:
        np.savez_compressed(fh, times=np.asarray(times, dtype=np.float64), images=stack)


def read_image_stream(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
    """The timestamps ``(N,)`` and images ``(N, H, W)`` of a sidecar image stream."""
    p = Path(path)
    try:
        with np.load(p) as data:
            for key in ("times", "images"):
                if key not in data.files:
                    raise InputError("not an image stream: missing", path=p, field=key)
            times, images = np.asarray(data["times"]), np.asarray(data["images"])
    except (OSError, ValueError) as exc:
        raise InputError(f"not an image stream: {exc}", path=p) from exc
    if images.dtype != np.uint8 or len(times) != len(images):
        raise InputError("an image stream needs one 8-bit image per timestamp", path=p, field="images")
    return times, images


def read_camera_images(
    path: str | Path, topic: str | None = None
) -> tuple[NDArray[np.float64], NDArray[np.uint8]]:
    """A camera's images with their times from a sidecar image stream (``.npz``) or a ROS 1 / ROS 2
    bag (``sensor_msgs/Image`` or ``CompressedImage``, ``topic`` or the one camera topic)."""
    p = Path(path)
    if p.suffix == ".npz":
        if topic is not None:
            raise InputError("an image stream holds one camera: no topic to choose", path=p, field="topic")
        return read_image_stream(p)
    from tourbot.io.rosbag import read_bag_images

    return read_bag_images(p, topic)
