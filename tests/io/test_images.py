"""Raw frame files and images: read whole, written whole, errors naming the file."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from tourbot.errors import InputError
from tourbot.io.images import read_gray_image, read_raw_frames, write_png


def test_raw_frames_round_trip_and_bad_size(tmp_path: Path) -> None:
    frames = np.arange(2 * 6 * 4, dtype=np.uint8).reshape(2, 6, 4)
    f = tmp_path / "f.raw.gz"
    f.write_bytes(gzip.compress(frames.tobytes()))
    assert np.array_equal(read_raw_frames(f, 4, 6), frames)
    with pytest.raises(InputError, match=r"f.raw.gz \(field size\)"):
        read_raw_frames(f, 5, 6)


def test_png_round_trip_colour_converted_and_errors(tmp_path: Path) -> None:
    img = (np.arange(30 * 40) % 256).astype(np.uint8).reshape(30, 40)
    p = tmp_path / "a" / "img.png"
    write_png(p, img)
    assert np.array_equal(read_gray_image(p), img)
    write_png(p, np.dstack([img, img, img]))
    assert read_gray_image(p).shape == (30, 40)
    bad = tmp_path / "bad.png"
    bad.write_text("not an image")
    with pytest.raises(InputError, match=r"bad.png \(field image\)"):
        read_gray_image(bad)
    with pytest.raises(InputError, match="no such image"):
        read_gray_image(tmp_path / "none.png")


def test_image_stream_round_trip_and_errors(tmp_path: Path) -> None:
    from tourbot.io.images import read_image_stream, write_image_stream

    imgs = [np.full((4, 5), k, dtype=np.uint8) for k in range(3)]
    p = tmp_path / "s.npz"
    write_image_stream(p, [0.0, 1.0, 2.0], imgs)
    times, images = read_image_stream(p)
    assert times.tolist() == [0.0, 1.0, 2.0]
    assert np.array_equal(images, np.stack(imgs))
    np.savez(tmp_path / "other.npz", stuff=np.zeros(3))
    with pytest.raises(InputError, match=r"other.npz \(field times\)"):
        read_image_stream(tmp_path / "other.npz")
