"""Mitsuba 3's `measured` BSDF at random direction pairs: the reference for our reader.

For each `.bsdf` file, draws direction pairs (half uniform on the hemisphere, half near the
mirror direction, where the data's mass is) and records Mitsuba's `eval / cos θo` (the BRDF
without the cosine), `pdf`, and `sample` for uniform variates (direction and pdf), in
`scalar_rgb`. Used two ways:

    # golden values for the Rust tests (small, committed under fixtures/measured/)
    python tools/measured_reference.py --pairs 256 --out fixtures/measured/mitsuba_reference.json \\
        fixtures/measured/*.bsdf
    # the full agreement check (bindings/python/tests/test_measured.py calls `reference`)

Needs `mitsuba` (3.9.1) and numpy.
"""

import argparse
import json
import os
import sys

import numpy as np


def directions(rng, n):
    """`n` (wi, wo) pairs in the upper hemisphere and `n` variates in [0, 1)²."""
    def uniform(k):
        u = rng.random((k, 2))
        z = u[:, 0]
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        phi = 2 * np.pi * u[:, 1]
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)

    wi = uniform(n)
    wo = uniform(n)
    # Half the pairs near the mirror direction (the data's peak): a small random tilt.
    half = n // 2
    mirror = wi[:half] * np.array([-1.0, -1.0, 1.0])
    tilt = rng.normal(scale=0.15, size=(half, 3))
    near = mirror + tilt
    near[:, 2] = np.abs(near[:, 2]) + 1e-3
    wo[:half] = near / np.linalg.norm(near, axis=1, keepdims=True)
    wi = np.clip(wi, -1, 1)
    wi[:, 2] = np.maximum(wi[:, 2], 1e-3)
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    u = rng.random((n, 2))
    return wi.astype(np.float32), wo.astype(np.float32), u.astype(np.float32)


def reference(path, wi, wo, u):
    """Mitsuba's f (÷ cos θo), pdf, and sampled (wo, pdf) for each pair, as float64 arrays."""
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    import drjit as dr

    bsdf = mi.load_dict({"type": "measured", "filename": os.fspath(path)})
    ctx = mi.BSDFContext()
    n = len(wi)
    f = np.zeros((n, 3))
    pdf = np.zeros(n)
    s_wo = np.zeros((n, 3))
    s_pdf = np.zeros(n)
    for i in range(n):
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(*map(float, wi[i]))
        d = mi.Vector3f(*map(float, wo[i]))
        v = bsdf.eval(ctx, si, d)
        cos = float(wo[i][2])
        f[i] = [v[0] / cos, v[1] / cos, v[2] / cos]
        pdf[i] = bsdf.pdf(ctx, si, d)
        bs, _ = bsdf.sample(ctx, si, 0.5, mi.Point2f(float(u[i][0]), float(u[i][1])))
        if bs.pdf > 0 and bs.wo[2] > 0:
            s_wo[i] = [bs.wo[0], bs.wo[1], bs.wo[2]]
            s_pdf[i] = bs.pdf
    return f, pdf, s_wo, s_pdf


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--pairs", type=int, default=256)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    out = {"mitsuba": None, "pairs": a.pairs, "seed": a.seed, "files": {}}
    import mitsuba as mi

    out["mitsuba"] = mi.__version__
    for k, path in enumerate(a.files):
        rng = np.random.default_rng(a.seed + k)
        wi, wo, u = directions(rng, a.pairs)
        f, pdf, s_wo, s_pdf = reference(path, wi, wo, u)
        out["files"][os.path.basename(path)] = {
            "wi": wi.tolist(),
            "wo": wo.tolist(),
            "u": u.tolist(),
            "f": f.tolist(),
            "pdf": pdf.tolist(),
            "sample_wo": s_wo.tolist(),
            "sample_pdf": s_pdf.tolist(),
        }
        print(f"{path}: {a.pairs} pairs", file=sys.stderr)
    tmp = a.out + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(out, fh, separators=(",", ":"))
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
