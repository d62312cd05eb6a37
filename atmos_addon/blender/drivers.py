# SPDX-License-Identifier: GPL-3.0-or-later
"""The drivers Atmos writes: each a fresh curve (no modifiers, no keys, no variables) with single-property variables,
so Blender evaluates it without Python (an Average of one variable, or a simple expression) and a farm machine without
the add-on, or a file opened with scripts disabled, renders it. Shared by :mod:`.apply.compositor` (the Per Pixel
group's inputs) and :mod:`.apply.sun_drivers` (the sun's parameters and lamp)."""

from __future__ import annotations


def fresh(owner, path: str, index: int | None = None, expression: str | None = None):
    """The driver curve of ``owner``'s ``path`` (element ``index``), created or reset in place: no modifiers, no keys
    (a driver curve with keys maps the driver's value through them), no variables; an Average without
    ``expression``, else scripted with it."""
    curve = owner.driver_add(path, index) if index is not None else owner.driver_add(path)
    for modifier in list(curve.modifiers):
        curve.modifiers.remove(modifier)
    curve.keyframe_points.clear()
    driver = curve.driver
    driver.type = "AVERAGE" if expression is None else "SCRIPTED"
    while driver.variables:
        driver.variables.remove(driver.variables[0])
    if expression is not None:
        driver.expression = expression
    return curve


def add_variable(driver, id_type: str, idblock, data_path: str, name: str | None = None) -> None:
    """A single-property variable of ``driver`` reading ``idblock``'s ``data_path``."""
    variable = driver.variables.new()
    if name is not None:
        variable.name = name
    variable.type = "SINGLE_PROP"
    variable.targets[0].id_type = id_type
    variable.targets[0].id = idblock
    variable.targets[0].data_path = data_path
