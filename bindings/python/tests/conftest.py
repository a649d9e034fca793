"""Shared fixtures of the neusample pytest suite."""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
FIXTURES = ROOT / "fixtures"
MATERIALS = ["goat_leather_neural", "brushed_metal_neural", "victorian_fabric_neural"]
METHODS = ["baseline", "analytic", "flow", "affine-flow", "direct-histogram", "histogram-mixture"]


# CI sets NEUSAMPLE_REQUIRE_MITSUBA=1: there a missing Mitsuba or Dr.Jit fails the tests that
# need it instead of skipping them.
REQUIRE_MITSUBA = os.environ.get("NEUSAMPLE_REQUIRE_MITSUBA") == "1"


def optional(setup):
    """``(setup(), "")``, or ``(None, why)`` when ``setup`` (the imports and checks a test module
    needs of Mitsuba or Dr.Jit) raises; under ``NEUSAMPLE_REQUIRE_MITSUBA=1`` it raises."""
    try:
        return setup(), ""
    except Exception as e:  # noqa: BLE001 - any failure to get the backend or variant
        if REQUIRE_MITSUBA:
            raise
        return None, str(e)


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
    """Prints the Dr.Jit agreement figures, the χ² p-values and the render means."""
    _drjit_summary(terminalreporter.write_line)
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
    if tm.REPARAM_RESULTS:
        w("")
        w("reparam, symbolic plugin vs the Rust plugin (4096 lanes): largest relative difference of "
          "the weight and of bs.pdf (at the Rust plugin's directions); share of lanes where "
          "p̂/q differs from 1 by > 1 %")
        for material, w_err, p_err, off in tm.REPARAM_RESULTS:
            w(f"{material:<24} {w_err:>9.2e} {p_err:>9.2e} {off:>7.3f}")


def _drjit_summary(w):
    try:
        import test_drjit as td
    except Exception:  # noqa: BLE001 - module skipped or not collected
        return
    if not td.RESULTS:
        return
    w("")
    w(f"Dr.Jit runtime vs Rust scalar ({td.LANES} lanes, LLVM, f32): largest relative pdf error at "
      f"the same directions, share of lanes above {td.PDF_RTOL}, sample lanes refused differently, "
      f"lanes moved > {td.SAMPLE_ATOL}; materials: largest relative error of f and φ")
    w(f"{'blob':<62} {'α':>5} {'pdf err':>9} {'>1e-4':>8} {'refused≠':>9} {'moved':>8}")
    for name, alpha, a, b, c, d in td.RESULTS:
        w(f"{name:<62} {alpha:>5.2f} {a:>9.2e} {b:>8.2e} {c:>9.2e} {d:>8.2e}")
    samplers = [r for r in td.RESULTS if not r[0].startswith("fixtures/materials")]
    for label, rows in (("flows", [r for r in samplers if "flow" in r[0]]),
                        ("other kinds", [r for r in samplers if "flow" not in r[0]])):
        if rows:
            worst = max(rows, key=lambda r: r[2])
            w(f"worst pdf error, {label}: {worst[2]:.3e} ({worst[0]})")
    if td.REPARAM_Q:
        name, err = max(td.REPARAM_Q, key=lambda r: r[1])
        w(f"reparam, the warp's sample density (N(z)/det J) at the same uniforms: largest relative "
          f"difference {err:.2e} ({name}; bound {td.REPARAM_Q_RTOL})")
    for name, r, d, x in td.FLOW_F64:
        w(f"{name} against its f64 evaluation: Rust f32 {r:.2e}, Dr.Jit f32 {d:.2e} "
          f"(Dr.Jit vs Rust {x:.2e})")
