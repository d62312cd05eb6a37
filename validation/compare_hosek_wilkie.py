# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's Hosek-Wilkie Sky Texture against the complete spectral reference sky, direction by direction.

    .venv/bpy-5.2.3/bin/python validation/compare_hosek_wilkie.py [--also .venv/bpy-4.5.15/bin/python]
        [--paths 1000] [--seed 0] [--output docs/hosek_wilkie.md]

Two skies of the same atmosphere, seen from the ground, sun at :data:`SUN_ELEVATIONS_DEG`, in the views of
:data:`VIEWS` (the zenith; 5 and 30 deg above the horizon toward the sun, across it at 90 deg of azimuth, and
away from it):

* **Hosek-Wilkie** (Hosek & Wilkie 2012, "An Analytic Model for Full Spectral Sky-Dome Radiance", ACM TOG
  31(4)): Blender's Sky Texture with ``sky_type='HOSEK_WILKIE'`` rendered in Cycles, the way
  ``tools/compare_sky_texture.py`` renders the other Sky Texture models: one tiny perspective camera
  (:data:`~tools.compare_sky_texture.FIELD_OF_VIEW_DEG` field of view,
  :data:`~tools.compare_sky_texture.RESOLUTION_PX` px square) per view, a linear 32-bit OpenEXR read back,
  the mean of its pixels. Cycles evaluates the model's CIE XYZ dataset and converts it to scene-linear
  Rec.709 with a D65 white (``intern/cycles/scene/shader.cpp``, ``ShaderManager::init_xyz_transforms``);
  the sun is given by ``sun_direction`` (the model has no sun disc in Cycles). Ground albedo
  :data:`GROUND_ALBEDO`. Hosek-Wilkie is fitted for solar elevations 0 to 90 deg only (Cycles clamps the
  sun's zenith angle to 90 deg, ``sky_texture_precompute_hosek``): it is not defined below the horizon, so no
  sun below it is compared.
* **The reference**: :func:`validation.spectral_reference.spectral_radiance` (backward Monte Carlo
  over every scattering order, 48 wavelengths 360-830 nm, ASTM G173 sun, CIE 1931 -> linear Rec.709) for the
  clear preset (``presets.load("clear")``), ozone :data:`OZONE_DU` DU and ground albedo
  :data:`GROUND_ALBEDO`, the settings of ``validation/measure_reference_sky.py``; again without ozone as a
  diagnostic (fixed seeds: the two runs are correlated, so their difference is more precise than either).

**Turbidity.** Preetham, Shirley & Smits 1999 ("A Practical Analytic Model for Daylight", SIGGRAPH 99)
define the turbidity as T = (t_m + t_h) / t_m, the optical thickness of the atmosphere with haze over that of
the molecules alone, and relate it to Angstrom's turbidity coefficient in their appendix (and their code,
``RiSunConstants.C``): beta = 0.04608365822050 T - 0.04586025928522, with the aerosol optical depth
tau_a(lambda) = beta (lambda / 1 um)^-alpha and alpha = 1.3. The clear preset's aerosol (extinction
4.44e-5 1/m at 550 nm at the ground, the part of its 70 km visibility that is not Rayleigh, scale height
1.2 km, Angstrom alpha 1.3) has a vertical optical depth tau_a(550 nm) = beta_ex,M(550) H_M, so beta =
tau_a(550) 0.55^alpha and T = (beta + 0.04586025928522) / 0.04608365822050: :func:`preetham_turbidity`,
the turbidity compared first. Turbidity is a column quantity, so it is taken from the preset's column, not
from its ground-level visibility alone. The definition itself at 550 nm, 1 + tau_a / tau_R, is printed beside
it as a check. Turbidities :data:`BRACKET_TURBIDITIES` (Blender's manual: 2 "arctic like", 3 "clear sky") are
rendered too, as a bracket.

**Compared** (scale-free: the two models have different absolute units): the luminance relative to the
zenith's, Y(view) / Y(zenith), with Y the CIE 1931 Y of linear Rec.709 RGB (row 2 of
:data:`~atmos_addon.physics.spectrum.LINEAR_REC709_TO_XYZ`: 0.2126 R + 0.7152 G + 0.0722 B) or, for the
reference, of its spectrum; and the CIE 1931 chromaticity xy (:func:`~atmos_addon.physics.spectrum.chromaticity_xy`).
Flagged: every ratio of relative luminances (Hosek-Wilkie / reference) off 1 by more than
:data:`LUMINANCE_TOLERANCE`, every |dx| or |dy| over :data:`XY_TOLERANCE`.

``--output`` rewrites the generated block of the report (the hand-written text around it is kept); without
it the block is printed. ``--also PYTHON`` renders with another interpreter's ``bpy`` too (in a subprocess,
``--measure-json``); the first interpreter's renders are the ones compared, the others are checked against
them. Default cost: about 4 min on one core (the reference; the renders take seconds).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))  # run as a script: the repository's packages

from atmos_addon import presets
from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.visibility import visibility_m
from atmos_addon.physics.spectrum import (
    ANGSTROM_REFERENCE_WAVELENGTH_NM,
    LINEAR_REC709_TO_XYZ,
    WAVELENGTHS_NM,
    chromaticity_xy,
)
from validation.spectral_reference import (
    XYZ_WEIGHTS,
    aerosol_angstrom_fit,
    linear_stderr,
    ratio_and_stderr,
    spectral_coefficients,
    spectral_radiance,
)
from tools.bench import publish_generated_block  # one definition for the report tools
from tools.compare_sky_texture import (add_blender_options, measure_in_each_blender, render_direction,
                                        repo_relative, setup_scene, unit_vector, wrote_measure_json)

#: Sun elevations compared, deg (all above the horizon: Hosek-Wilkie is not defined below it).
SUN_ELEVATIONS_DEG = (60.0, 20.0, 5.0, 1.0)
#: Views from the ground: name -> (elevation, azimuth measured from the sun's), deg.
VIEWS = {"zenith": (90.0, 0.0),
         "5 toward": (5.0, 0.0), "5 across": (5.0, 90.0), "5 away": (5.0, 180.0),
         "30 toward": (30.0, 0.0), "30 across": (30.0, 90.0), "30 away": (30.0, 180.0)}
#: Ground albedo of both models (the reference's, and Blender's MULTIPLE_SCATTERING sky's).
GROUND_ALBEDO = 0.3
#: Ozone column of the reference, Dobson units (as ``validation/measure_reference_sky.py``).
OZONE_DU = 300.0
#: Paths per view and wavelength of the reference (each of its two runs); about 4 min on one core in all.
DEFAULT_PATHS = 1000
#: Turbidities rendered besides the clear preset's (Blender's manual: 2 "arctic like", 3 "clear sky").
BRACKET_TURBIDITIES = (2.0, 3.0)
#: Flag: |Y_rel(Hosek-Wilkie) / Y_rel(reference) - 1| above this.
LUMINANCE_TOLERANCE = 0.10
#: Flag: |dx| or |dy| of the CIE 1931 chromaticity above this.
XY_TOLERANCE = 0.01
#: Preetham et al. 1999, appendix: Angstrom's beta = slope T + offset, for alpha = 1.3 and lambda in um.
PREETHAM_BETA_SLOPE = 0.04608365822050
PREETHAM_BETA_OFFSET = -0.04586025928522
PREETHAM_ALPHA = 1.3
#: CIE 1931 Y of linear Rec.709 RGB (D65): 0.2126 R + 0.7152 G + 0.0722 B.
Y_OF_REC709 = LINEAR_REC709_TO_XYZ[1]

BEGIN_MARK = "<!-- BEGIN GENERATED by validation/compare_hosek_wilkie.py -->"
END_MARK = "<!-- END GENERATED -->"


# --- turbidity ------------------------------------------------------------------------------------------------

def preetham_turbidity(atmosphere: Atmosphere) -> dict[str, float]:
    """Preetham et al. 1999's turbidity of an atmosphere's aerosol column, with the numbers it comes from.

    tau_a: vertical aerosol optical depth at 550 nm, beta_ex,M(550) H_M (the exponential layer's column; the
    extinction at 550 nm from the Angstrom fit of :func:`~validation.spectral_reference.aerosol_angstrom_fit`);
    tau_r: the Rayleigh one at 550 nm, beta_R(550) H_R (Bodhaine et al. 1999 through
    :func:`~validation.spectral_reference.spectral_coefficients`). ``beta``: Angstrom's turbidity
    coefficient tau_a(1 um) = tau_a(550) 0.55^alpha with the atmosphere's own alpha. ``turbidity``: Preetham's
    appendix inverted, (beta - offset) / slope (valid for alpha = 1.3, which Preetham assume; ``alpha`` is
    returned so that the caller can see it). ``turbidity_definition``: 1 + tau_a / tau_r at 550 nm, Preetham's
    definition T = (t_m + t_h) / t_m taken at one wavelength, as a check. ``visibility_km``: Koschmieder's
    -ln(0.02) / beta_ex(550 nm) at the ground, the quantity the preset is defined by (its aerosol is what is left
    of that extinction after Rayleigh's).
    """
    fit = aerosol_angstrom_fit(atmosphere)
    visibility_km = visibility_m(atmosphere) / 1000.0
    tau_a = fit["extinction_550_per_m"] * float(atmosphere.mie_scale_height)
    at_550 = int(np.flatnonzero(WAVELENGTHS_NM == ANGSTROM_REFERENCE_WAVELENGTH_NM)[0])
    tau_r = float(spectral_coefficients(atmosphere)["rayleigh_scattering"][at_550]) * float(
        atmosphere.rayleigh_scale_height)
    beta = tau_a * (ANGSTROM_REFERENCE_WAVELENGTH_NM / 1000.0) ** fit["alpha"]
    return {"visibility_km": visibility_km, "tau_aerosol_550": tau_a, "tau_rayleigh_550": tau_r, "alpha": fit["alpha"], "beta": beta,
            "turbidity": (beta - PREETHAM_BETA_OFFSET) / PREETHAM_BETA_SLOPE,
            "turbidity_definition": 1.0 + tau_a / tau_r}


def turbidities() -> tuple[float, ...]:
    """The clear preset's turbidity (:func:`preetham_turbidity`, rounded to 0.01), then the bracket."""
    return (round(preetham_turbidity(presets.load("clear").atmosphere)["turbidity"], 2), *BRACKET_TURBIDITIES)


# --- colour ---------------------------------------------------------------------------------------------------

def luminance(rgb) -> np.ndarray:
    """CIE 1931 Y of linear Rec.709 RGB on the last axis (same unit as the RGB)."""
    return np.asarray(rgb, dtype=np.float64) @ Y_OF_REC709


def xy_of_rgb(rgb) -> np.ndarray:
    """CIE 1931 chromaticity (x, y) of linear Rec.709 RGB on the last axis, through XYZ (D65)."""
    return chromaticity_xy(np.asarray(rgb, dtype=np.float64) @ LINEAR_REC709_TO_XYZ.T)


def relative_luminance(rgb_by_view: dict[str, list[float]]) -> dict[str, float]:
    """Y(view) / Y(zenith) of a {view: linear Rec.709 RGB} dict that has a "zenith" entry (1 at the zenith)."""
    zenith = float(luminance(rgb_by_view["zenith"]))
    return {name: float(luminance(rgb)) / zenith for name, rgb in rgb_by_view.items()}


def view_vector(elevation_deg: float, azimuth_from_sun_deg: float) -> np.ndarray:
    """Unit view direction, z up, the sun's azimuth along +x (azimuth from +x toward +y)."""
    return unit_vector(elevation_deg, azimuth_from_sun_deg)


def angle_from_sun_deg(sun_elevation_deg: float, view: str) -> float:
    """Angle between the view :data:`VIEWS` [view] and the sun at ``sun_elevation_deg`` (azimuth 0), deg."""
    cosine = float(view_vector(*VIEWS[view]) @ view_vector(sun_elevation_deg, 0.0))
    return math.degrees(math.acos(min(1.0, max(-1.0, cosine))))


# --- Blender (bpy) --------------------------------------------------------------------------------------------

def render_hosek_wilkie(turbidity: float, sun_elevations_deg=SUN_ELEVATIONS_DEG, views=None,
                        ground_albedo: float = GROUND_ALBEDO) -> dict[str, dict[str, list[float]]]:
    """Blender's Hosek-Wilkie sky in Cycles: {str(sun elevation): {view name: mean linear Rec.709 RGB}}.

    ``views``: {name: (elevation, azimuth from the sun's)} in deg (default :data:`VIEWS`); the sun is at
    azimuth 0 (+x), set through the node's ``sun_direction``. RGB in Blender's units (the model's XYZ times
    2 pi / 683, converted to scene-linear Rec.709); only ratios of them mean anything here. Loads a factory
    scene (the current file is replaced).
    """
    import bpy

    views = VIEWS if views is None else views
    result: dict[str, dict[str, list[float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        scene, sky, camera = setup_scene(bpy, "HosekWilkie")
        sky.sky_type = "HOSEK_WILKIE"
        if hasattr(sky, "sun_disc"):
            sky.sun_disc = False
        sky.turbidity = float(turbidity)
        sky.ground_albedo = float(ground_albedo)
        for sun_elevation in sun_elevations_deg:
            sky.sun_direction = tuple(view_vector(sun_elevation, 0.0))
            result[f"{sun_elevation:g}"] = {
                name: render_direction(bpy, scene, camera, elevation, azimuth,
                                        Path(tmp) / f"view{k}.exr").tolist()
                for k, (name, (elevation, azimuth)) in enumerate(views.items())}
    return result


def measure_blender() -> dict:
    """Every turbidity of :func:`turbidities` rendered at every sun and view; Blender's version; seconds."""
    import bpy

    start = time.perf_counter()
    renders = {f"{t:g}": render_hosek_wilkie(t) for t in turbidities()}
    return {"blender": bpy.app.version_string, "renders": renders,
            "seconds": round(time.perf_counter() - start, 1)}


# --- the reference (numpy) ------------------------------------------------------------------------------------

def measure_reference(paths: int, seed: int, ozone_du: float) -> dict:
    """The clear preset's reference sky in :data:`VIEWS`: per sun, relative luminance and xy with standard errors.

    {str(sun): {"Y_rel": (k,), "Y_rel_se": (k,), "xy": (k, 2), "xy_se": (k, 2), "Y": (k,)}} in the order of
    :data:`VIEWS` (Y in W m^-2 sr^-1, no 683 lm/W). The views are traced with independent paths, so the
    relative error of Y_rel is the root sum of squares of those of Y(view) and Y(zenith).
    """
    clear = presets.load("clear").atmosphere
    directions = np.array([view_vector(*v) for v in VIEWS.values()])
    zenith = list(VIEWS).index("zenith")
    total = XYZ_WEIGHTS.sum(axis=1)
    results = {}
    for sun_elevation in SUN_ELEVATIONS_DEG:
        spectrum, stderr = spectral_radiance(directions, view_vector(sun_elevation, 0.0), atmosphere=clear,
                                             ozone_du=ozone_du, ground_albedo=GROUND_ALBEDO, paths=paths,
                                             seed=seed)
        y = spectrum @ XYZ_WEIGHTS[:, 1]
        y_se = linear_stderr(stderr, XYZ_WEIGHTS[:, 1])
        x, x_se = ratio_and_stderr(spectrum, stderr, XYZ_WEIGHTS[:, 0], total)
        yy, yy_se = ratio_and_stderr(spectrum, stderr, XYZ_WEIGHTS[:, 1], total)
        y_rel = y / y[zenith]
        y_rel_se = y_rel * np.hypot(y_se / y, y_se[zenith] / y[zenith])
        y_rel_se[zenith] = 0.0  # 1 by construction
        results[f"{sun_elevation:g}"] = {"Y": y, "Y_rel": y_rel, "Y_rel_se": y_rel_se,
                                         "xy": np.column_stack([x, yy]), "xy_se": np.column_stack([x_se, yy_se])}
        print(f"reference, ozone {ozone_du:g} DU, sun {sun_elevation:g}: zenith xy {x[zenith]:.4f} "
              f"{yy[zenith]:.4f}", file=sys.stderr, flush=True)
    return results


# --- comparison -----------------------------------------------------------------------------------------------

def compare(renders: dict[str, dict[str, list[float]]], reference: dict) -> list[dict]:
    """One row per (sun, view): Hosek-Wilkie's and the reference's Y_rel and xy, their ratio and differences.

    ``renders``: :func:`render_hosek_wilkie`'s result for one turbidity; ``reference``: :func:`measure_reference`'s.
    ``flags``: "Y" when |ratio - 1| > :data:`LUMINANCE_TOLERANCE`, "xy" when |dx| or |dy| > :data:`XY_TOLERANCE`.
    """
    rows = []
    for sun in (f"{e:g}" for e in SUN_ELEVATIONS_DEG):
        hw_rel = relative_luminance(renders[sun])
        ref = reference[sun]
        for k, view in enumerate(VIEWS):
            hw_xy = xy_of_rgb(renders[sun][view])
            ratio = hw_rel[view] / float(ref["Y_rel"][k])
            dxy = hw_xy - ref["xy"][k]
            flags = (["Y"] if abs(ratio - 1.0) > LUMINANCE_TOLERANCE else []) + (
                ["xy"] if np.max(np.abs(dxy)) > XY_TOLERANCE else [])
            rows.append({"sun": sun, "view": view, "hw_y_rel": hw_rel[view], "ref_y_rel": float(ref["Y_rel"][k]),
                         "ref_y_rel_se": float(ref["Y_rel_se"][k]), "ratio": ratio, "hw_xy": hw_xy.tolist(),
                         "ref_xy": ref["xy"][k].tolist(), "ref_xy_se": ref["xy_se"][k].tolist(),
                         "dxy": dxy.tolist(), "flags": flags})
    return rows


def _max_relative_difference(a: dict, b: dict) -> float:
    """Largest |a / b - 1| over every turbidity, sun, view and channel of two :func:`measure_blender` renders."""
    worst = 0.0
    for t, suns in a.items():
        for sun, views in suns.items():
            for view, rgb in views.items():
                other = np.asarray(b[t][sun][view])
                worst = max(worst, float(np.max(np.abs(np.asarray(rgb) / other - 1.0))))
    return worst


def markdown(runs: list[dict], reference_on: dict, reference_off: dict, turbidity_info: dict, command: str,
             paths: int, seed: int, seconds: dict[str, float]) -> str:
    """The generated block of docs/hosek_wilkie.md."""
    main, *others = runs
    t_clear, *bracket = turbidities()
    key = f"{t_clear:g}"
    lines = [BEGIN_MARK, "",
             f"Produced by `{command}` in {seconds['total']:.0f} s wall time (reference: {seconds['reference']:.0f} s "
             f"for two runs of {paths} paths per view and wavelength, seed {seed}; renders: "
             + ", ".join(f"Blender {r['blender']} {r['seconds']:.0f} s" for r in runs) + ").", "",
             (f"Turbidity of the clear preset (visibility {turbidity_info['visibility_km']:.1f} km at 550 nm; "
              f"Preetham et al. 1999): vertical aerosol optical depth at 550 nm "
             f"tau_a = {turbidity_info['tau_aerosol_550']:.4f}, Rayleigh tau_R = {turbidity_info['tau_rayleigh_550']:.4f}, "
             f"Angstrom alpha {turbidity_info['alpha']:.3f}, beta = tau_a 0.55^alpha = {turbidity_info['beta']:.4f}; "
             f"T = (beta + 0.04586) / 0.04608 = **{turbidity_info['turbidity']:.3f}** (rendered as {t_clear:g}); "
             f"the definition 1 + tau_a / tau_R at 550 nm gives {turbidity_info['turbidity_definition']:.3f}. "
             f"Bracket: T = {', '.join(f'{t:g}' for t in bracket)}. Ground albedo {GROUND_ALBEDO} in both models; "
             f"reference ozone {OZONE_DU:g} DU (and 0 as a diagnostic). Suns below the horizon: not compared "
             f"(Hosek-Wilkie is not defined there)."), ""]
    for run in others:
        lines += [(f"Blender {run['blender']} renders the same Hosek-Wilkie skies as Blender {main['blender']} to "
                  f"{_max_relative_difference(run['renders'], main['renders']):.1e} (largest relative difference "
                  f"of any channel)."), ""]

    rows = compare(main["renders"][key], reference_on)
    lines += [(f"**Hosek-Wilkie T = {t_clear:g} (Blender {main['blender']}) against the reference (clear preset, "
              f"ozone {OZONE_DU:g} DU)**. Y_rel = Y(view) / Y(zenith); ratio = Y_rel(HW) / Y_rel(ref.); ± one "
              f"standard error of the reference; flags: Y when the ratio is off 1 by more than "
              f"{100 * LUMINANCE_TOLERANCE:.0f} %, xy when |dx| or |dy| > {XY_TOLERANCE}."), "",
              "| sun | view | angle from the sun | Y_rel HW | Y_rel ref. | ratio | x, y HW | x, y ref. | dx | dy | flags |",
              "|---:|---|---:|---:|---:|---:|---|---|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r['sun']} | {r['view']} | {angle_from_sun_deg(float(r['sun']), r['view']):.0f} "
                     f"| {r['hw_y_rel']:.3f} | {r['ref_y_rel']:.3f} ± "
                     f"{r['ref_y_rel_se']:.3f} | {r['ratio']:.3f} | {r['hw_xy'][0]:.4f}, {r['hw_xy'][1]:.4f} "
                     f"| {r['ref_xy'][0]:.4f}, {r['ref_xy'][1]:.4f} ± {max(r['ref_xy_se']):.4f} "
                     f"| {r['dxy'][0]:+.4f} | {r['dxy'][1]:+.4f} | {' '.join(r['flags']) or '-'} |")
    lines.append("")

    comparisons = [(f"T {t_clear:g} / ozone on", compare(main["renders"][key], reference_on)),
                   (f"T {t_clear:g} / ozone 0", compare(main["renders"][key], reference_off))]
    comparisons += [(f"T {t:g} / ozone on", compare(main["renders"][f"{t:g}"], reference_on)) for t in bracket]
    lines += [("**All comparisons**, ratio of relative luminances (HW / ref.) and dx, dy (HW - ref.), each Hosek-Wilkie "
              "turbidity against the reference with ozone (\"ozone on\") or without (\"ozone 0\"):"), "",
              "| sun | view | " + " | ".join(f"{label}: ratio, dx, dy" for label, _ in comparisons) + " |",
              "|---:|---|" + "---|" * len(comparisons)]
    for i, r in enumerate(rows):
        cells = [f"{c[i]['ratio']:.3f}, {c[i]['dxy'][0]:+.3f}, {c[i]['dxy'][1]:+.3f}" for _, c in comparisons]
        lines.append(f"| {r['sun']} | {r['view']} | " + " | ".join(cells) + " |")
    lines.append("")

    lines += ["**Reference without ozone**: Y_rel and x, y (the diagnostic run).", "",
              "| sun | view | Y_rel | x, y |", "|---:|---|---:|---|"]
    for sun in (f"{e:g}" for e in SUN_ELEVATIONS_DEG):
        ref = reference_off[sun]
        for k, view in enumerate(VIEWS):
            lines.append(f"| {sun} | {view} | {ref['Y_rel'][k]:.3f} ± {ref['Y_rel_se'][k]:.3f} "
                         f"| {ref['xy'][k][0]:.4f}, {ref['xy'][k][1]:.4f} |")
    lines.append("")

    flagged = [r for r in rows if r["flags"]]
    lines += [(f"**Flagged** (T = {t_clear:g} against the reference with ozone): {len(flagged)} of {len(rows)} "
              f"(sun, view) pairs; luminance {sum('Y' in r['flags'] for r in rows)}, chromaticity "
              f"{sum('xy' in r['flags'] for r in rows)}."), "",
              (f"Raw linear Rec.709 RGB of the renders (Blender {main['blender']}, Blender's units), per "
               f"turbidity and sun, in the order " + ", ".join(VIEWS) + ":"), "", "```"]
    for t, suns in main["renders"].items():
        for sun, views in suns.items():
            lines.append(f"T {t:>4} sun {sun:>2}: " + "; ".join(" ".join(f"{c:.4g}" for c in views[v]) for v in VIEWS))
    lines += ["```", "", END_MARK]
    return "\n".join(lines)


HEADER = """# Hosek-Wilkie against the reference sky

<!-- The hand-written text goes around the generated block. -->

"""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--paths", type=int, default=DEFAULT_PATHS, help="reference paths per view and wavelength")
    parser.add_argument("--seed", type=int, default=0)
    add_blender_options(parser, "docs/hosek_wilkie.md")
    args = parser.parse_args(argv)
    if wrote_measure_json(args, measure_blender):
        return 0
    start = time.perf_counter()
    runs = measure_in_each_blender(measure_blender, Path(__file__), args.also)
    for run in runs:
        print(f"Blender {run['blender']}: {run['seconds']} s of renders", file=sys.stderr)
    reference_start = time.perf_counter()
    reference_on = measure_reference(args.paths, args.seed, OZONE_DU)
    reference_off = measure_reference(args.paths, args.seed, 0.0)
    seconds = {"reference": time.perf_counter() - reference_start}
    seconds["total"] = time.perf_counter() - start
    command = (f"{repo_relative(sys.executable)} validation/compare_hosek_wilkie.py --paths {args.paths}"
               f" --seed {args.seed}"
               + "".join(f" --also {p}" for p in args.also) + (f" --output {args.output}" if args.output else ""))
    generated = markdown(runs, reference_on, reference_off, preetham_turbidity(presets.load("clear").atmosphere),
                         command, args.paths, args.seed, seconds)
    publish_generated_block(args.output, generated, BEGIN_MARK, END_MARK, HEADER)
    return 0


if __name__ == "__main__":
    sys.exit(main())
