# SPDX-License-Identifier: GPL-3.0-or-later
"""tools/measure_sun_free_table.py: its 4-D table's mappings invert, and its lookup is the table at the texels, so the
figures docs/quality.md quotes from it measure Bruneton's parametrisation and not a slip of the study."""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tools"))

import measure_sun_free_table as study  # noqa: E402

from atmos_addon.physics import Atmosphere  # noqa: E402
from atmos_addon.presets import load  # noqa: E402


def test_the_texel_parameters_map_back_to_their_texels():
    for atm in (Atmosphere(), load("mars").atmosphere):
        geometry = study.Geometry(atm)
        r, mu, mu_s, nu, ground = geometry.texel_parameters()
        coords = geometry.coordinates(r, mu, mu_s, nu, ground)
        sizes = (study.R_SIZE, study.MU_SIZE, study.MU_S_SIZE, study.NU_SIZE)
        indices = np.meshgrid(*(np.arange(n, dtype=float) for n in sizes), indexing="ij")
        defined = ~(ground & (indices[0] == 0))   # at the ground itself every ray down has length 0: one mu
        for axis in range(3):
            np.testing.assert_allclose(coords[axis][defined], indices[axis][defined], atol=1e-4)   # of a texel
        unclamped = np.isclose(nu, indices[3] * 2.0 / (study.NU_SIZE - 1) - 1.0, rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(coords[3][unclamped], indices[3][unclamped], atol=1e-9)
        assert np.all(mu[ground] <= 0.0) and np.all(mu_s >= study.MU_S_MIN - 1e-12)


def test_the_lookup_is_the_table_at_the_texels_and_linear_between():
    rng = np.random.default_rng(1)
    table = rng.uniform(0.0, 1.0, (3, 4, 5, 6, 3)).astype(np.float32)
    at = [np.array([2.0, 0.0]), np.array([1.0, 3.0]), np.array([4.0, 2.0]), np.array([5.0, 1.0])]
    np.testing.assert_array_equal(study.lookup(table, at), table[(2, 0), (1, 3), (4, 2), (5, 1)])
    middle = study.lookup(table, [np.array([0.5]), np.array([1.0]), np.array([2.0]), np.array([3.0])])
    np.testing.assert_allclose(middle[0], 0.5 * (table[0, 1, 2, 3] + table[1, 1, 2, 3]), rtol=1e-6)


def test_a_coarse_run_measures_both_tables(monkeypatch):
    """End to end on a small 4-D table: every error finite, the tile's within what docs/quality.md reports of it (a
    few % of the horizon sky at most), the coarse 4-D table's far larger (its sizes matter: the measure sees them)."""
    from atmos_addon.physics import precise
    for name, n in (("R_SIZE", 4), ("MU_SIZE", 16), ("MU_S_SIZE", 4), ("NU_SIZE", 2)):
        monkeypatch.setattr(study, name, n)
    atm = Atmosphere()
    tables = precise.atmosphere_tables(atm)
    table = study.build_table(atm, tables)
    assert table[0].shape == (4, 16, 4, 2, 3) and np.all(np.isfinite(table[0])) and np.all(table[0] >= 0.0)
    run = study.compare(atm, tables, table, 100.0, 5.0)
    for key in ("tile", "table_4d", "tile_vs_haze", "table_4d_vs_haze", "tile_ms_block_vs_haze"):
        assert np.all(np.isfinite(run[key])), key
    assert np.max(run["tile_vs_haze"]) < 0.05 and np.max(run["tile_ms_block_vs_haze"]) < 0.05
    assert np.percentile(run["table_4d_vs_haze"], 99) > 3.0 * np.percentile(run["tile_vs_haze"], 99)
