# SPDX-License-Identifier: GPL-3.0-or-later
"""What Atmos is measured against, kept out of the shipped extension (``paths_exclude_pattern`` in
``blender_manifest.toml``).

Brute-force references: :mod:`.reference` (single scattering by quadrature), :mod:`.multiple_scattering_reference`
(every order, backward Monte Carlo) and :mod:`.spectral_reference` (that Monte Carlo on 48 wavelengths, CIE 1931 ->
Rec.709); :mod:`.balanced`, the closed-form Balanced model, kept for comparison. :mod:`.accuracy` is the accuracy
bench (situations, references, error measure) and :mod:`.visibility` a black target's contrast by the reference and
by each level. The scripts beside them store reference data for the tests and report the references
(each docstring gives its command). Imports ``atmos_addon.physics``; the add-on never imports this package.
"""
