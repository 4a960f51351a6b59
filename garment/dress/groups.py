"""Pattern panels as groups: the patches of each panel (a panel cut into pieces moves as
one), sets of panels joined where they share one, and what hangs from a panel through
its seams. Placement (layout.py, paths.py, halves.py) moves panels by these groups."""

from __future__ import annotations


def members(patches, panels) -> dict[str, list]:
    """{pattern panel: its patches, in order}; panels: each patch's panel."""
    out: dict[str, list] = {}
    for p, panel in zip(patches, panels):
        out.setdefault(panel, []).append(p)
    return out


def panel_names(patches, panels) -> tuple[dict[str, str], dict[str, list[str]]]:
    """({patch name: its pattern panel}, {pattern panel: its patches' names, in order})."""
    return dict(zip((p.name for p in patches), panels)), \
        {panel: [p.name for p in ps] for panel, ps in members(patches, panels).items()}


def merged(sets: list[set[str]]) -> list[set[str]]:
    """The sets, those that share a member joined."""
    out: list[set[str]] = []
    for g in sets:
        g = set(g)
        for other in [h for h in out if h & g]:
            out.remove(other)
            g |= other
        out.append(g)
    return out


def hanging(panels: set[str], links: list[tuple[str, str]], holding: set[str]) -> set[str]:
    """`panels` and every panel sewn to them, through any chain of seams (links: pairs of
    panels) that does not pass through the `holding` panels: a sleeve with its cuff."""
    out, grew = set(panels), True
    while grew:
        grew = False
        for a, b in links:
            for x, y in ((a, b), (b, a)):
                if x in out and y not in out and y not in holding:
                    out.add(y)
                    grew = True
    return out
