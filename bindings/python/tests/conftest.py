"""Shared fixtures of the neusample pytest suite."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
FIXTURES = ROOT / "fixtures"
MATERIALS = ["goat_leather_neural", "brushed_metal_neural", "victorian_fabric_neural"]
METHODS = ["baseline", "analytic", "flow", "affine-flow", "direct-histogram", "histogram-mixture"]


def material_path(material: str) -> str:
    return str(FIXTURES / "materials" / "neural" / f"{material}.nsb")


def sampler_path(material: str, method: str):
    """The fixture blob of `method` for `material` (None for cosine)."""
    if method == "cosine":
        return None
    return str(FIXTURES / "blobs" / material / f"{method}.nsb")


@pytest.fixture(scope="session")
def fixtures_dir() -> Path:
    return FIXTURES


def pytest_terminal_summary(terminalreporter):
    """Prints the χ² p-values and the render means of the Mitsuba tests."""
    try:
        import test_mitsuba as tm
    except Exception:  # noqa: BLE001 - module skipped or not collected
        return
    w = terminalreporter.write_line
    if tm.CHI2_RESULTS:
        w("")
        w(f"Mitsuba χ² (ChiSquareTest + BSDFAdapter, llvm_ad_rgb, {tm.SAMPLES} samples, "
          f"α = {tm.SIGNIFICANCE} Šidák-corrected over {tm.TEST_COUNT} runs)")
        w("brushed metal: pdf integrated at res 201, ires 8 (see RESOLUTION); others 101, 4")
        w(f"{'material':<24} {'sampler':<28} {'wi':>24} {'uv':>13} {'p-value':>9} {'result':>7} {'s':>5}")
        for material, method, _, wi, uv, p, ok, secs in tm.CHI2_RESULTS:
            wi_s = "(" + ", ".join(f"{x:.2f}" for x in wi) + ")"
            uv_s = "(" + ", ".join(f"{x:.2f}" for x in uv) + ")"
            w(f"{material:<24} {method:<28} {wi_s:>24} {uv_s:>13} {p:>9.3g} "
              f"{'pass' if ok else 'REJECT':>7} {secs:>5.2f}")
    if tm.RENDER_RESULTS:
        w("")
        w(f"Mitsuba render (goat leather patch under an environment map, path + MIS, 32×32, "
          f"64 spp vs a 256 spp cosine reference; bound: relative mean difference < {tm.RENDER_BOUND})")
        w(f"{'sampler':<20} {'mean':>9} {'ref mean':>9} {'rel diff':>9} {'RMSE':>9} {'s':>6}")
        for method, mean, ref, rel, rmse, secs in tm.RENDER_RESULTS:
            w(f"{method:<20} {mean:>9.5f} {ref:>9.5f} {rel:>9.4f} {rmse:>9.5f} {secs:>6.2f}")
