"""Summarises a `neusample demo` report over measured materials against the data's own
sampler (`measured-data`): per material, the best learned or analytic sampler by equal-time
speed-up over the improved baseline, its equal-spp variance and equal-time speed-up relative
to the data's sampler, and their KL / χ² to p* (for reparam, whose pdf is its MIS density,
also the χ² of the density its samples are drawn with). On a report without the data's
sampler (the neural route: the demo run on neural fits of the files) those columns read "—".

    python tools/measured_summary.py neusample-report/report.json
"""

import json
import sys

# The references; every other method of the report is a learned (or analytic) sampler.
REFERENCES = {"cosine", "baseline", "measured-data", "oracle"}


def fit_text(x):
    """KL and χ² of a method's pdf; for a sampler whose samples are drawn with another density
    (reparam: its pdf is the MIS density) also that density's χ², which sets the variance of
    BSDF sampling alone."""
    text = f"{x['kl_divergence']:.3f}, {x['chi2']:.3g}"
    if x.get("sampled"):
        text += f" (samples' χ² {x['sampled']['chi2']:.3g})"
    return text


def main(path):
    r = json.load(open(path))
    if not any(x.get("render") for m in r["materials"] for x in m["methods"]):
        sys.exit(f"{path}: no renders in this report (a `demo --no-render` run): render the "
                 "blobs with `neusample demo --blobs DIR/blobs` and summarise that report")
    print("| material | best learned | among learned and analytic | vs baseline, equal time | its variance / data's (equal spp) "
          "| its equal-time speed-up / data's | data's vs baseline | KL, χ² best learned | KL, χ² data | verdict |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---|")
    for m in r["materials"]:
        by = {x["method"]: x for x in m["methods"]}
        data = by.get("measured-data")
        cands = [x for x in m["methods"] if x["method"] not in REFERENCES and x.get("render")]
        best = max(cands, key=lambda x: x["render"]["speedup"]["value"])
        s = best["render"]["speedup"]
        # As the report's verdict, among the learned and analytic samplers alone: the best is
        # clear when every other's interval lies below its lower bound.
        tied = [x["method"] for x in cands
                if x is not best and not (x["render"]["speedup"]["hi"] < s["lo"])]
        among = "clear" if not tied else "tied with " + ", ".join(tied)
        v = m.get("verdict") or {}
        verdict = v.get("best", "") + (" (clear)" if v.get("clear") else
                                       " tied with " + ", ".join(v.get("tied_with", [])))
        fit = fit_text(best)
        head = (f"| {m['material']} | {best['method']} | {among} | {s['value']:.2f}× [{s['lo']:.2f}–{s['hi']:.2f}] ")
        if data is None:
            print(head + f"| — | — | — | {fit} | — | {verdict} |")
            continue
        d = data["render"]["speedup"]
        # Per-sample variance ratio at equal spp: variance_best / variance_data.
        var_ratio = best["render"]["variance"]["value"] / data["render"]["variance"]["value"]
        print(
            head + f"| {var_ratio:.2f} | {s['value'] / d['value']:.2f} "
            f"| {d['value']:.2f}× [{d['lo']:.2f}–{d['hi']:.2f}] "
            f"| {fit} | {fit_text(data)} "
            f"| {verdict} |"
        )


if __name__ == "__main__":
    main(sys.argv[1])
