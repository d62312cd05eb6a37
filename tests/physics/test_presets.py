# SPDX-License-Identifier: GPL-3.0-or-later
"""Presets: built-ins load, files round-trip exactly, bad files are refused with useful messages,
the library guards built-ins, and each built-in shows the colours it promises under the physics core."""

from __future__ import annotations

import importlib
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from atmos_addon import presets
from atmos_addon.physics import extinction, sun_irradiance_ground
from atmos_addon.physics.atmosphere import Atmosphere
from atmos_addon.physics.rayleigh import rayleigh_coefficients
from atmos_addon.physics.visibility import extinction_550_per_m
from atmos_addon.presets import Preset, PresetError, schema

BUILTINS = ("clear", "overcast", "sunset", "mars")
KOSCHMIEDER = 3.912  # -ln(0.02): 2 % contrast threshold


@pytest.fixture(autouse=True)
def _no_user_directory():
    """Every test starts and ends with no user folder set (module state)."""
    presets.set_user_directory(None)
    yield
    presets.set_user_directory(None)


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


def _custom_preset(name: str = "Desert haze") -> Preset:
    atm = Atmosphere(mie_scattering=[2.0e-5, 2.5e-5, 3.1e-5], mie_absorption=1.0e-7, mie_g=[0.7, 0.71, 0.72],
                     mie_scale_height=1500.0, sun_irradiance_top=[4.4, 4.5, 4.6])
    return presets.preset_from_atmosphere(name, atm, sun_elevation_deg=12.5, sun_azimuth_deg=-33.25,
                                          description='Dusty "afternoon"\nover sand', sources=["Made up, 2025."])


# ---------------------------------------------------------------------------------------------------------------
# Built-ins and the round trip


@pytest.mark.parametrize("name", BUILTINS)
def test_builtin_loads_and_validates(name):
    preset = presets.load(name)
    assert preset.name == name and preset.builtin and preset.path.name == f"{name}.toml"
    assert preset.description and preset.sources
    assert isinstance(preset.atmosphere, Atmosphere)
    assert presets.validate_file(preset.path) == preset


def test_names_lists_builtins_then_user_presets(tmp_path):
    assert presets.names() == list(BUILTINS)
    presets.save_user_preset(_custom_preset("zeta"), tmp_path)
    presets.save_user_preset(_custom_preset("Alpha"), tmp_path)
    _write(tmp_path, "Clear.toml", "")  # would shadow a built-in: left out
    _write(tmp_path, "bad.name.toml", "")  # not a valid name: left out
    _write(tmp_path, "notes.txt", "")
    assert presets.names(tmp_path) == [*BUILTINS, "Alpha", "zeta"]
    presets.set_user_directory(tmp_path)
    assert presets.names() == [*BUILTINS, "Alpha", "zeta"]
    assert presets.load("Alpha").path == tmp_path / "Alpha.toml"
    assert presets.load("clear").builtin  # the built-in wins over Clear.toml


@pytest.mark.parametrize("name", BUILTINS)
def test_builtin_round_trip_is_exact(name, tmp_path):
    preset = presets.load(name)
    again = presets.load(presets.save(preset, tmp_path / "copy.toml"))
    assert again == preset and not again.builtin
    assert presets.load(presets.save(again, tmp_path / "copy2.toml")) == preset


def test_custom_round_trip_is_exact(tmp_path):
    preset = _custom_preset()
    again = presets.load(presets.save(preset, tmp_path / "custom.toml"))
    assert again == preset
    assert again.description == 'Dusty "afternoon"\nover sand' and again.sun_azimuth_deg == -33.25
    assert np.array_equal(again.atmosphere.mie_g, [0.7, 0.71, 0.72])
    awkward = presets.preset_from_atmosphere(
        "awkward", Atmosphere(mie_scattering=[0.1 + 0.2, 1.0 / 3.0, 5e-324], rayleigh_scattering=[1e-300, 2.5e-6, 0]))
    assert presets.load(presets.save(awkward, tmp_path / "awkward.toml")) == awkward


def test_save_mapping_keeps_symbolic_rayleigh(tmp_path):
    doc = {"schema_version": 1, "preset": {"name": "sea", "sources": ("A", "B")},
           "atmosphere": {"rayleigh": "earth_standard", "mie_g": np.float64(0.7),
                          "mie_scattering_per_m": np.array([1e-5, 1e-5, 1e-5])}}
    path = presets.save(doc, tmp_path / "sea.toml")
    assert tomllib.loads(path.read_text())["atmosphere"]["rayleigh"] == "earth_standard"
    preset = presets.load(path)
    assert np.array_equal(preset.atmosphere.rayleigh_scattering, Atmosphere().rayleigh_scattering)
    assert preset.sources == ("A", "B") and preset.sun_elevation_deg is None


def test_missing_keys_take_clear_earth_defaults(tmp_path):
    path = _write(tmp_path, "bare.toml", 'schema_version = 1\n[preset]\nname = "bare"\n')
    preset = presets.load(path)
    assert preset.atmosphere == Atmosphere() and preset.description == "" and preset.sources == ()
    assert preset.sun_elevation_deg is None and preset.sun_azimuth_deg is None


def test_preset_from_atmosphere_checks_like_a_file():
    with pytest.raises(PresetError, match="path characters"):
        presets.preset_from_atmosphere("../up", Atmosphere())
    with pytest.raises(PresetError, match=r"\[sun\] elevation_deg.*\[-90, 90\]"):
        presets.preset_from_atmosphere("ok", Atmosphere(), sun_elevation_deg=91.0)


def test_schema_table_documents_every_key():
    table = schema.markdown_table()
    for spec in schema.FIELDS:
        assert f"`{spec.label}`" in table


# ---------------------------------------------------------------------------------------------------------------
# Bad files: refused, naming the file, the field and the rule

_HEAD = 'schema_version = 1\n[preset]\nname = "bad"\n'
_BAD_FILES = [
    # id, text, field, rule
    ("syntax", 'schema_version = 1\n[preset\nname = "bad"\n', "line 2", "TOML syntax error"),
    ("unknown table", _HEAD + "[atmosphre]\nmie_g = 0.7\n", "atmosphre", "did you mean 'atmosphere'"),
    ("unknown key", _HEAD + "[atmosphere]\nmie_scatering_per_m = [1e-5, 1e-5, 1e-5]\n",
     "[atmosphere] mie_scatering_per_m", "did you mean 'mie_scattering_per_m'"),
    ("key in wrong table", _HEAD + "[atmosphere]\nelevation_deg = 10.0\n", "[atmosphere] elevation_deg",
     "it belongs in [sun]"),
    ("wrong type", _HEAD + '[atmosphere]\nmie_g = "strong"\n', "[atmosphere] mie_g", "must be a number"),
    ("boolean for number", _HEAD + "[atmosphere]\nmie_scale_height_m = true\n", "[atmosphere] mie_scale_height_m",
     "must be a number"),
    ("table not a table", 'schema_version = 1\natmosphere = 3\n[preset]\nname = "bad"\n', "[atmosphere]",
     "must be a table"),
    ("table inside a table", _HEAD + "atmosphere = 3\n", "[preset] atmosphere", "[atmosphere] is a table"),
    ("wrong length", _HEAD + "[atmosphere]\nmie_scattering_per_m = [1e-5, 1e-5]\n",
     "[atmosphere] mie_scattering_per_m", "exactly 3 values"),
    ("negative coefficient", _HEAD + "[atmosphere]\nmie_absorption_per_m = [-1e-6, 0.0, 0.0]\n",
     "[atmosphere] mie_absorption_per_m[0]", "must be in [0, 1] 1/m"),
    ("g at 1", _HEAD + "[atmosphere]\nmie_g = 1.0\n", "[atmosphere] mie_g", "must be in (-1, 1)"),
    ("g per channel", _HEAD + "[atmosphere]\nmie_g = [0.5, -1.5, 0.5]\n", "[atmosphere] mie_g[1]", "(-1, 1)"),
    ("not finite", _HEAD + "[atmosphere]\nrayleigh_scale_height_m = nan\n", "[atmosphere] rayleigh_scale_height_m",
     "must be finite"),
    ("infinite", _HEAD + "[atmosphere]\nplanet_radius_m = inf\n", "[atmosphere] planet_radius_m", "must be finite"),
    ("zero scale height", _HEAD + "[atmosphere]\nmie_scale_height_m = 0\n", "[atmosphere] mie_scale_height_m",
     "must be in (0, 1e6] m"),
    ("sun too high", _HEAD + "[sun]\nelevation_deg = 95.0\n", "[sun] elevation_deg", "must be in [-90, 90] deg"),
    ("sun too low", _HEAD + "[sun]\nelevation_deg = -90.5\n", "[sun] elevation_deg", "[-90, 90]"),
    ("no schema_version", '[preset]\nname = "bad"\n', "schema_version", "is required but missing"),
    ("future schema_version", 'schema_version = 2\n[preset]\nname = "bad"\n', "schema_version", "not supported"),
    ("schema_version a string", 'schema_version = "1"\n[preset]\nname = "bad"\n', "schema_version",
     "must be an integer"),
    ("no preset table", "schema_version = 1\n", "[preset]", "table is required"),
    ("no name", "schema_version = 1\n[preset]\n", "[preset] name", "is required"),
    ("name with path", 'schema_version = 1\n[preset]\nname = "../../evil"\n', "[preset] name", "path characters"),
    ("name with backslash", 'schema_version = 1\n[preset]\nname = "a\\\\b"\n', "[preset] name", "not a valid"),
    ("reserved device name", 'schema_version = 1\n[preset]\nname = "NUL"\n', "[preset] name", "not a valid"),
    ("sources not strings", _HEAD + "sources = [1, 2]\n", "[preset] sources", "array of strings"),
    ("both rayleigh forms", _HEAD + '[atmosphere]\nrayleigh = "earth_standard"\n'
     "rayleigh_scattering_per_m = [1e-6, 1e-6, 1e-6]\n", "[atmosphere] rayleigh", "not both"),
    ("unknown rayleigh", _HEAD + '[atmosphere]\nrayleigh = "venus"\n', "[atmosphere] rayleigh",
     "must be one of 'earth_standard'"),
    ("both sun forms", _HEAD + "[atmosphere]\nsun_irradiance_top_scale = 0.5\n"
     "sun_irradiance_top_w_m2 = [1.0, 1.0, 1.0]\n", "[atmosphere] sun_irradiance_top_scale", "not both"),
]


@pytest.mark.parametrize(("text", "field", "rule"), [case[1:] for case in _BAD_FILES],
                         ids=[case[0] for case in _BAD_FILES])
def test_bad_file_is_refused_with_file_field_and_rule(tmp_path, text, field, rule):
    path = _write(tmp_path, "broken_preset.toml", text)
    with pytest.raises(PresetError) as caught:
        presets.validate_file(path)
    message = str(caught.value)
    assert "broken_preset.toml" in message and field in message and rule in message, message
    assert caught.value.field == field and caught.value.path == str(path)


def test_huge_file_is_refused_before_parsing(tmp_path, monkeypatch):
    path = _write(tmp_path, "huge.toml", _HEAD + "# padding\n" * 7000)
    assert path.stat().st_size > 64 * 1024

    def parse(*_args, **_kwargs):
        raise AssertionError("a huge file must not be parsed")

    monkeypatch.setattr(tomllib, "loads", parse)
    with pytest.raises(PresetError, match=r"huge\.toml: file size: .* over the 64 KiB limit"):
        presets.validate_file(path)


def test_non_utf8_and_missing_files_are_refused(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(_HEAD.encode() + b'description = "caf\xe9"\n')
    with pytest.raises(PresetError, match=r"latin1\.toml: byte \d+: is not UTF-8"):
        presets.validate_file(path)
    with pytest.raises(PresetError, match=r"nothere\.toml: no such preset file"):
        presets.load(tmp_path / "nothere.toml")
    with pytest.raises(PresetError, match="no preset of that name; known presets: clear, overcast"):
        presets.load("nothere")


def test_loading_never_executes_code(tmp_path, monkeypatch):
    """A file is parsed as data: text that looks like code is only ever a string, and refused as a name."""
    called = []
    monkeypatch.setattr("builtins.__import__", lambda *a, **k: called.append(a) or importlib.__import__(*a, **k))
    path = _write(tmp_path, "code.toml", 'schema_version = 1\n[preset]\nname = "__import__(\'os\').system(\'x\')"\n')
    with pytest.raises(PresetError, match="not a valid preset name"):
        presets.validate_file(path)
    assert not any(args and args[0] == "os" for args in called)


# ---------------------------------------------------------------------------------------------------------------
# The user library


def test_builtins_cannot_be_deleted_or_renamed(tmp_path):
    presets.save_user_preset(_custom_preset("mine"), tmp_path)
    for name in ("clear", "Mars", "SUNSET"):
        with pytest.raises(PresetError, match="built-in preset"):
            presets.delete_user_preset(name, tmp_path)
        with pytest.raises(PresetError, match="built-in preset"):
            presets.rename_user_preset(name, "other", tmp_path)
        with pytest.raises(PresetError, match="built-in preset"):
            presets.rename_user_preset("mine", name, tmp_path)
        with pytest.raises(PresetError, match="built-in preset"):
            presets.save_user_preset(_custom_preset(name), tmp_path)
    assert presets.load("clear").path.is_file()


def test_user_library_operations(tmp_path):
    folder = tmp_path / "user"
    with pytest.raises(PresetError, match="no user preset folder is set"):
        presets.delete_user_preset("mine")
    presets.set_user_directory(folder)
    path = presets.save_user_preset(_custom_preset("mine"))
    assert path == folder / "mine.toml"
    with pytest.raises(PresetError, match="exists"):
        presets.save_user_preset(_custom_preset("mine"))
    presets.rename_user_preset("mine", "yours")
    assert presets.names() == [*BUILTINS, "yours"] and not path.exists()
    assert presets.load("yours").name == "yours" and presets.load("yours").atmosphere == _custom_preset().atmosphere
    presets.rename_user_preset("yours", "Yours")  # change of case only
    assert presets.names() == [*BUILTINS, "Yours"]
    with pytest.raises(PresetError, match="path characters"):
        presets.rename_user_preset("Yours", "../x")
    presets.delete_user_preset("Yours")
    assert presets.names() == list(BUILTINS)
    with pytest.raises(PresetError, match="no user preset of that name"):
        presets.delete_user_preset("Yours")


def test_import_and_export(tmp_path):
    folder = tmp_path / "user"
    exported = presets.export_preset("mars", tmp_path / "out" / "red planet.toml")
    assert exported.read_bytes() == (presets.BUILTIN_DIRECTORY / "mars.toml").read_bytes()
    with pytest.raises(PresetError, match="built-in preset"):
        presets.import_preset(exported, folder)  # its name is "mars"
    source = presets.save(_custom_preset("dune"), tmp_path / "downloads" / "dune-v2.toml")
    source.write_text(source.read_text() + "# a comment kept by import\n")
    imported = presets.import_preset(source, folder)
    assert imported.name == "dune" and imported.path == folder / "dune.toml" and not imported.builtin
    assert imported.path.read_bytes() == source.read_bytes()
    with pytest.raises(PresetError, match="exists"):
        presets.import_preset(source, folder)
    assert presets.import_preset(source, folder, overwrite=True) == imported
    broken = _write(tmp_path, "broken.toml", _HEAD + "[atmosphere]\nmie_g = 2.0\n")
    with pytest.raises(PresetError, match="broken.toml"):
        presets.import_preset(broken, folder)
    assert presets.names(folder) == [*BUILTINS, "dune"]


def test_library_file_name_must_match_preset_name(tmp_path):
    presets.save(_custom_preset("inner"), tmp_path / "outer.toml")
    with pytest.raises(PresetError, match=r"outer\.toml: \[preset\] name: is 'inner' but the file is outer\.toml"):
        presets.load("outer", tmp_path)


# ---------------------------------------------------------------------------------------------------------------
# The numbers in the files are the ones their comments derive


def _visibility_m(atm: Atmosphere) -> float:
    """Koschmieder meteorological visibility V = 3.912 / beta_ex at 550 nm (each species read at 550 nm), m."""
    return KOSCHMIEDER / extinction_550_per_m(atm)


def test_stated_visibilities():
    assert 50e3 <= _visibility_m(presets.load("clear").atmosphere) <= 100e3
    for name, stated_m in (("clear", 70e3), ("overcast", 10e3), ("sunset", 40e3)):
        assert _visibility_m(presets.load(name).atmosphere) == pytest.approx(stated_m, rel=1e-3)


def test_mars_numbers_follow_from_their_sources():
    atm = presets.load("mars").atmosphere
    co2 = rayleigh_coefficients(atm.wavelengths_nm, pressure_pa=610.0, temperature_k=210.0, king_factor=1.15) * 1.5**2
    np.testing.assert_allclose(atm.rayleigh_scattering, co2, rtol=1e-3)
    np.testing.assert_allclose(atm.sun_irradiance_top, Atmosphere().sun_irradiance_top / 1.5237**2, rtol=1e-3)
    dust = atm.mie_extinction
    np.testing.assert_allclose(dust * atm.mie_scale_height, 0.5, rtol=2e-3)  # dust optical depth
    np.testing.assert_allclose(atm.mie_scattering / dust, [0.97, 0.94, 0.75], rtol=2e-3)  # single-scattering albedo
    assert atm.planet_radius == 3389.5e3 and atm.rayleigh_scale_height == 11.1e3


def test_readme_table_is_the_schema():
    readme = (Path(presets.__file__).parent / "README.md").read_text(encoding="utf-8")
    assert schema.markdown_table() in readme


# ---------------------------------------------------------------------------------------------------------------
# What each built-in looks like under the physics core
#
# Sky radiance: the brute-force single-scattering integral (``validation.reference.single_scattering``)
# along the view ray from the ground to the top of the atmosphere over the spherical planet: the physical
# truth each preset is judged by. The shipped sky model (``physics.sky``, the virtual dome lit by the
# ground-level sun) is checked against the same colour conditions in the last test of this file.


def _direction(elevation_deg: float, azimuth_deg: float = 0.0) -> np.ndarray:
    """Unit vector, z up, azimuth measured in the x-y plane."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def _sky(atm: Atmosphere, sun_elevation_deg: float, view_elevation_deg: float, azimuth_from_sun_deg: float
         ) -> np.ndarray:
    """Sky radiance (R, G, B) seen from the ground, W/(m^2 sr) for the preset's top-of-atmosphere sun."""
    view, sun = _direction(view_elevation_deg, azimuth_from_sun_deg), _direction(sun_elevation_deg)
    from validation import reference

    radius, top = atm.planet_radius, atm.atmosphere_height
    sin_e = view[2]
    to_top = -radius * sin_e + math.sqrt((radius * sin_e) ** 2 + 2.0 * radius * top + top * top)
    return reference.single_scattering(0.0, view, to_top, sun, atm, n_steps=401, n_sun_steps=129)[1]


def test_clear_noon_zenith_is_blue():
    zenith = _sky(presets.load("clear").atmosphere, 60.0, 90.0, 0.0)
    assert zenith[2] > zenith[1] > zenith[0]


def test_sunset_sun_is_orange_and_the_horizon_toward_it_red():
    preset = presets.load("sunset")
    assert preset.sun_elevation_deg == 2.0 and preset.sun_azimuth_deg is None
    sun = sun_irradiance_ground(math.radians(preset.sun_elevation_deg), preset.atmosphere)
    assert sun[0] > sun[1] > sun[2] > 0.0
    horizon = _sky(preset.atmosphere, preset.sun_elevation_deg, 1.0, 15.0)
    assert horizon[0] > horizon[1] > horizon[2] > 0.0


def test_mars_day_sky_is_butterscotch():
    sky = _sky(presets.load("mars").atmosphere, 40.0, 30.0, 180.0)
    assert sky[0] > sky[1] > sky[2] > 0.0


def test_mars_sunset_glow_is_blue():
    atm = presets.load("mars").atmosphere
    near = _sky(atm, 2.0, 2.0, 3.0)  # 3 deg from the sun
    for azimuth in (60.0, 90.0, 180.0):
        far = _sky(atm, 2.0, 2.0, azimuth)
        assert near[2] / near[0] > 2.0 * far[2] / far[0]
    assert near[2] > near[0]


def test_overcast_is_grey_and_low_contrast():
    overcast, clear = presets.load("overcast").atmosphere, presets.load("clear").atmosphere
    # Grey: the sky keeps the colour of the sun above the atmosphere (slightly warm, the solar spectrum's).
    for view in ((90.0, 0.0), (30.0, 90.0), (10.0, 180.0), (45.0, 0.0), (5.0, 30.0)):
        sky = _sky(overcast, 45.0, *view) / overcast.sun_irradiance_top
        assert sky.max() / sky.min() < 1.4
    for view in ((90.0, 0.0), (30.0, 90.0), (10.0, 180.0)):  # away from the sun's (white in both) aureole
        sky = _sky(overcast, 45.0, *view) / overcast.sun_irradiance_top
        blue = _sky(clear, 45.0, *view) / clear.sun_irradiance_top
        assert sky.max() / sky.min() < 0.6 * (blue.max() / blue.min())
    zenith = _sky(overcast, 45.0, 90.0, 0.0) / overcast.sun_irradiance_top
    assert zenith.max() / zenith.min() < 1.2
    assert np.all(extinction(5000.0, overcast) < 0.5)  # a black object 5 km away keeps under half its contrast


def test_builtin_looks_hold_in_the_shipped_sky_model():
    """The colour conditions of the presets also hold for the sky the add-on renders (dome model, ground E_sun)."""
    from atmos_addon.physics import sky, sun_irradiance_ground

    def dome_sky(name: str, sun_elevation_deg: float, view_elevation_deg: float, azimuth_deg: float) -> np.ndarray:
        atm = presets.load(name).atmosphere
        e_sun = sun_irradiance_ground(math.radians(sun_elevation_deg), atm)
        return sky.sky_radiance(_direction(view_elevation_deg, azimuth_deg), _direction(sun_elevation_deg), atm, e_sun)

    zenith = dome_sky("clear", 60.0, 90.0, 0.0)
    assert zenith[2] > zenith[1] > zenith[0]
    horizon = dome_sky("sunset", 2.0, 1.0, 15.0)
    assert horizon[0] > horizon[1] > horizon[2]
    mars_day = dome_sky("mars", 40.0, 30.0, 180.0)
    assert mars_day[0] > mars_day[1] > mars_day[2]
    near, far = dome_sky("mars", 2.0, 2.0, 3.0), dome_sky("mars", 2.0, 2.0, 60.0)
    assert near[2] / near[0] > 2.0 * far[2] / far[0]
