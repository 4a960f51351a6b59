"""Seams, in one place: what a seam is (`spec`), the matched samples the energy and the
contact exclusions use (`samples`), piece meshes stitched along seams (`mesh`), the seam
energy (`energy`), matched contact vertices merging as seams close (`contact`), and the
sewing policy that ramps, holds and releases them over a run (`sewing`)."""
