"""PNG plots of the compare benchmark (matplotlib, optional: without it, none are drawn)."""

from __future__ import annotations

from pathlib import Path


def write(rows: list[dict], folder: Path) -> list[Path]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    written = []

    def save(fig, name):
        path = folder / name
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    pairs = [r for r in rows if "seconds_per_step_linear" in r and r["case"] in ("hanging", "drape", "shear", "sphere")]
    if pairs:
        fig, ax = plt.subplots(figsize=(6, 3.5))
        labels = [f"{r['case']}\n{r['resolution']}² / {r['linear_resolution']}²" for r in pairs]
        x = range(len(pairs))
        ax.bar([i - 0.2 for i in x], [r["seconds_per_step_bspline"] for r in pairs], 0.4, label="B-spline")
        ax.bar([i + 0.2 for i in x], [r["seconds_per_step_linear"] for r in pairs], 0.4, label="linear FEM")
        ax.set_xticks(list(x), labels)
        ax.set_ylabel("seconds per step")
        ax.legend()
        save(fig, "pairs_seconds_per_step.png")

    plate = [r for r in rows if r["case"] == "plate" and "rel_error" in r]
    if plate:
        fig, ax = plt.subplots(figsize=(5, 4))
        for method in dict.fromkeys(r["method"] for r in plate):
            pts = sorted((r["seconds"], r["rel_error"]) for r in plate if r["method"] == method)
            ax.loglog(*zip(*pts), "o-", label=method)
        ax.set_xlabel("seconds (build + solve)")
        ax.set_ylabel("relative error of the centre deflection")
        ax.legend()
        save(fig, "plate_error_vs_runtime.png")

    locking = [r for r in rows if r["case"] == "locking"]
    if locking:
        fig, ax = plt.subplots(figsize=(6, 4))
        for ratio, style in zip(dict.fromkeys(r.get("E_sh_ratio") for r in locking), ("-", "--", ":")):
            series = [r for r in locking if r.get("E_sh_ratio") == ratio]
            E = [r["E_st"] for r in series]
            for key, label in (("sag_m_bspline", "B-spline"), ("sag_m_linear_crossing", "linear, fold across edges"),
                               ("sag_m_linear_aligned", "linear, fold along edges")):
                ax.semilogx(E, [r[key] for r in series], "o" + style, label=f"{label} (E_sh/E_st {ratio:g})")
        ax.set_xlabel("E_st (Pa)")
        ax.set_ylabel("sag at rest (m)")
        ax.legend(fontsize=7)
        save(fig, "locking_sag.png")

    ablation = [r for r in rows if r["case"] == "ablation"]
    if ablation:
        fig, ax = plt.subplots(figsize=(5, 4))
        bottom = [0.0] * len(ablation)
        for key in ("assembly", "factorization", "solve", "line_search", "other"):
            vals = [1e3 * r[f"{key}_seconds"] for r in ablation]
            ax.bar([r["variant"] for r in ablation], vals, bottom=bottom, label=key)
            bottom = [b + v for b, v in zip(bottom, vals)]
        ax.set_ylabel("ms per Newton iteration")
        ax.legend()
        save(fig, "ablation_breakdown.png")
    return written
