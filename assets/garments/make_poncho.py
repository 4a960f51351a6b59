"""Write poncho.obj: a two-panel poncho for the Rumba body (the demo garment, CC0).

Two 0.56 m x 0.60 m rectangles hang in front of and behind the body's rest pose (Z-up,
feet at z = 0), their top edges 3 cm above the shoulders; the top edges are sewn
together over each shoulder (|x| >= 0.11 m), leaving a 0.22 m neck opening. The format
is the panel OBJ of garment/io/panels.py: `vt` flat layout, `v` 3D placement, `g` panels,
`seam`/`stitch` lines (0-based `v` indices). Run: python make_poncho.py > poncho.obj
"""

import numpy as np

WIDTH, HEIGHT, SPACING = 0.56, 0.60, 0.02
TOP = 1.30  # m: 3 cm above the shoulders (1.27 m)
PLANES = {"front": 0.17, "back": -0.09}  # m: chest at y <= 0.132, back at y >= -0.056
NECK = 0.11  # m: half-width of the unsewn neck opening


def main() -> None:
    nx, nz = round(WIDTH / SPACING) + 1, round(HEIGHT / SPACING) + 1
    s, t = np.meshgrid(np.linspace(0, WIDTH, nx), np.linspace(0, HEIGHT, nz), indexing="ij")
    flat = np.c_[s.ravel(), t.ravel()]  # vertex i * nz + j
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(nz - 1), indexing="ij")
    v = (i * nz + j).ravel()
    alt = ((i + j) % 2 == 0).ravel()  # alternating diagonals
    tris = np.r_[np.where(alt[:, None], np.c_[v, v + nz, v + nz + 1], np.c_[v, v + nz, v + 1]),
                 np.where(alt[:, None], np.c_[v, v + nz + 1, v + 1], np.c_[v + 1, v + nz, v + nz + 1])]
    print("# poncho: two panels sewn over the shoulders (assets/garments/make_poncho.py)")
    n = len(flat)
    for name, y in PLANES.items():
        for x, z in flat:
            print(f"v {x - WIDTH / 2:.6f} {y:.6f} {TOP - HEIGHT + z:.6f}")
    for _ in PLANES:
        for x, z in flat:
            print(f"vt {x:.6f} {z:.6f}")
    for k, name in enumerate(PLANES):
        print(f"g {name}")
        for a, b, c in tris + 1 + k * n:
            print(f"f {a}/{a} {b}/{b} {c}/{c}")
    top = np.arange(nx) * nz + nz - 1  # top-edge vertices, left to right
    x = flat[top, 0] - WIDTH / 2
    for side in (x <= -NECK, x >= NECK):
        ids = top[side]
        print(f"seam {len(ids)}")
        for a in ids:
            print(f"stitch {a} {a + n} {a + n} 0")


if __name__ == "__main__":
    main()
