"""The episode animation: full resolution, the env's frame rate, colours kept."""

from __future__ import annotations

import numpy as np
from PIL import Image

from nbv_gym.env.render import save_animation


def test_gif_keeps_every_pixel_and_the_frame_rate(tmp_path):
    rng = np.random.default_rng(0)
    palette = rng.integers(0, 256, (40, 3), dtype=np.uint8)  # fewer colours than a GIF holds
    frames = [palette[rng.integers(0, 40, (52, 104))] for _ in range(3)]
    frames[-1][:, :] = palette[np.arange(104) % 40]  # the last frame holds all 40 colours
    path = tmp_path / "a.gif"
    save_animation(frames, path, fps=2)
    gif = Image.open(path)
    assert gif.size == (104, 52) and gif.n_frames == 3
    for k, frame in enumerate(frames):
        gif.seek(k)
        assert gif.info["duration"] == 500  # 1000 ms / render_fps
        np.testing.assert_array_equal(np.asarray(gif.convert("RGB")), frame)
