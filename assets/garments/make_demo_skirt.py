"""Write skirt_makehuman.json: the demo's skirt (skirt_panels.json, GarmentCode corpus
design skirt_00, MIT) graded to the CC0 MakeHuman body.

GarmentCode sampled the skirt for its `mean_all` body, whose waist where the skirt's top
sits (0.635 of the height) measures 0.85 m around; the MakeHuman body's measures 0.67 m.
Dressed as sampled, the skirt (0.84 m at its top) hangs loose and slides down the legs
during the jumps. Grading keeps its length and shape and scales every width, and its
placement around the vertical axis, by GRADE: 0.84 m -> 0.76 m at the top, which the
hips below hold up, 1.09 m -> 0.98 m at the hem. (At 0.8 the hem squeezed the hips and
trapped a hand against them at the second landing.) Panels are vertical (rotated about
Y only), so a panel's x is horizontal; the hem arcs' radii scale with their edges.
Run: python make_demo_skirt.py > skirt_makehuman.json
"""

import json
from pathlib import Path

GRADE = 0.9  # the top: 0.76 m, between the waist (0.67 m) and the hips


def main() -> None:
    spec = json.loads((Path(__file__).parent / "skirt_panels.json").read_text())
    for panel in spec["pattern"]["panels"].values():
        assert panel["rotation"][0] in (0.0, -0.0, -180.0), "a panel not rotated about Y only"
        panel["vertices"] = [[GRADE * x, y] for x, y in panel["vertices"]]
        x, y, z = panel["translation"]
        panel["translation"] = [GRADE * x, y, GRADE * z]
        for edge in panel["edges"]:
            curve = edge.get("curvature")
            if curve and curve.get("type") == "circle":  # horizontal hem: radius scales with it
                curve["params"][0] *= GRADE
    print(json.dumps(spec, indent=1))


if __name__ == "__main__":
    main()
