"""Writes examples/textures/neon-sign.png: a neon sign's tubes (a ring, a wave and a star) on a transparent ground, for
examples/neon-sign.toml, where its alpha cuts the sign's panel down to the tubes and its colour tints their light;
and neon-sign-back.png, the same upside down, for the panel's back (turned half a turn about x to face the wall).
Run from the repository root:
    python examples/textures/make_neon_sign.py
"""

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

OUT = Path(__file__).parent / "neon-sign.png"
BACK = Path(__file__).parent / "neon-sign-back.png"
SIZE = (512, 256)
PINK, CYAN, AMBER = (255, 70, 190), (60, 220, 255), (255, 180, 60)


def build() -> Image.Image:
    image = Image.new("RGBA", SIZE, (0, 0, 0, 0))
    draw = ImageDraw.Draw(image)
    draw.ellipse((24, 40, 200, 216), outline=PINK + (255,), width=14)
    x = np.linspace(222, 352, 200)
    wave = list(zip(x, 128 + 60 * np.sin((x - 222) / 130 * 3 * np.pi)))
    draw.line(wave, fill=CYAN + (255,), width=14, joint="curve")
    angles = np.radians(np.arange(10) * 36 - 90)
    radii = np.where(np.arange(10) % 2 == 0, 80, 34)
    star = [(432 + r * np.cos(a), 128 + r * np.sin(a)) for r, a in zip(radii, angles)]
    draw.line(star + star[:1], fill=AMBER + (255,), width=12, joint="curve")
    return image


if __name__ == "__main__":
    sign = build()
    sign.save(OUT)
    sign.transpose(Image.Transpose.FLIP_TOP_BOTTOM).save(BACK)
    print(f"wrote {OUT} and {BACK}")
