"""Error against cost of the light build's gather (issue 34 item 2): docs/images/gather_cost_error.png.

The figures are measurements from 2026-11-27 (docs/rendering.md, "Shared gather paths", and for
the sixth point "The sun pass walks the voxels", measured that evening against the previous
default's 1,100-1,177 ms in the same session) and for the last 2026-11-28 (the segment's ends of
2026-11-27 and the transport density, "The solve's faces take each cell's transport density":
the default since then, its build alternated with the one before, 1,273-1,283 ms): the
build's lavapipe ms for a 64^3 stormscape volume (`vdbcook bench storm.vdbc --modes lit --width
64 --height 36 --blend hold --frames 20 --runs 3 --json --ms-gather N`, build = (playing mean -
static) / 0.4, the range over the runs), and over the nine sunlit scenes of
tools/lighting/sunlight_scenes.txt whose assets were at hand the mean |1 - mean ratio| and the
mean relative RMSE against 8192-spp references (tools/lighting/sunlight.sh). Re-measure and edit
the table to redraw.

    python3 tools/lighting/gather_cost_chart.py docs/images/gather_cost_error.png
"""
import sys
from PIL import Image, ImageDraw, ImageFont
pts = [  # label, build ms (range), bias, rmse
    ("ms_gather 0", (343, 426), 0.0616, 0.1055),
    ("ms_gather 1 (shared)", (687, 699), 0.0352, 0.0815),
    ("2, shared from level 1", (1032, 1068), 0.0282, 0.0748),
    ("2, shared from level 2", (1270, 1563), 0.0272, 0.0737),
    ("2, each cell's path", (2069, 2172), 0.0267, 0.0733),
    ("2, shared, exact sun pass", (1280, 1505), 0.0142, 0.0683),
    ("+ segment ends, transport density (default)", (1285, 1337), 0.0111, 0.0645),
]
W, H = 1100, 520
img = Image.new("RGB", (W, H), "white")
d = ImageDraw.Draw(img)
try:
    font = ImageFont.truetype("DejaVuSans.ttf", 14)
    small = ImageFont.truetype("DejaVuSans.ttf", 12)
except OSError:
    font = small = ImageFont.load_default()
cols = [(90, 90, 90), (40, 120, 200), (200, 60, 40), (230, 150, 30), (60, 160, 80), (140, 60, 170),
        (20, 170, 170)]
def panel(x0, title, idx, ymax):
    L, T, R, B = x0 + 60, 50, x0 + 520, 400
    d.text((L, 15), title, fill="black", font=font)
    d.line([(L, B), (R, B)], fill="black"); d.line([(L, T), (L, B)], fill="black")
    xmax = 2400.0
    for v in range(0, 2401, 400):
        x = L + (R - L) * v / xmax
        d.line([(x, B), (x, B + 5)], fill="black"); d.text((x - 12, B + 8), str(v), fill="black", font=small)
    d.text(((L + R) / 2 - 120, B + 28), "build, ms (lavapipe, 64³ stormscape volume)", fill="black", font=small)
    steps = 5
    for k in range(steps + 1):
        v = ymax * k / steps
        y = B - (B - T) * v / ymax
        d.line([(L - 5, y), (L, y)], fill="black"); d.text((x0 + 8, y - 7), "%.3f" % v, fill="black", font=small)
        d.line([(L + 1, y), (R, y)], fill=(230, 230, 230))
    for (label, (lo, hi), bias, rmse), c in zip(pts, cols):
        v = (bias, rmse)[idx]
        y = B - (B - T) * v / ymax
        xl, xh = L + (R - L) * lo / xmax, L + (R - L) * hi / xmax
        d.line([(xl, y), (xh, y)], fill=c, width=3)
        xm = (xl + xh) / 2
        d.ellipse([xm - 5, y - 5, xm + 5, y + 5], fill=c)
panel(0, "mean |1 − lit/reference| over 9 sunlit scenes", 0, 0.07)
panel(550, "mean relative RMSE over 9 sunlit scenes", 1, 0.12)
y = 462
x = 20
for (label, _, _, _), c in zip(pts, cols):
    w = 14 + d.textlength(label, font=small) + 24
    if x + w > W:
        x, y = 20, y + 22
    d.ellipse([x, y + 3, x + 10, y + 13], fill=c); d.text((x + 14, y), label, fill="black", font=small)
    x += w
img.save(sys.argv[1])
