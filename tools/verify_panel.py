# SPDX-License-Identifier: GPL-3.0-or-later
"""The Atmosphere panel in a GUI Blender at the Properties editor's default width: screenshots, a cut-text check.

Run by ``CHECK=panel tools/verify_viewport_chroot.sh`` (GUI Blender under Xvfb in a Debian chroot), or by hand::

    xvfb-run -a -s '-screen 0 1280x2400x24' blender --factory-startup --python tools/verify_panel.py -- --out DIR [--zip dist/atmos-0.1.0.zip]

Blender opens with its factory layout on a screen 1280 px wide (the width at which issue 29 found labels cut; the
layout scales its areas with the window, so a wider screen only widens the editor), the valley sample scene and
``enable(preset="clear")``. Every Atmosphere sub-panel is opened (the ones closed by default too) and the World tab
is shown. For each engine (Eevee, Cycles) and the effect on and off it

* takes a screenshot of the Properties editor from the X server (ImageMagick's ``import``; Blender's own
  ``screen.screenshot_area`` gives a black image under Xvfb + llvmpipe): ``DIR/panel_<engine>_<on|off>.png``;
* records every text the panels drew in that redraw (a layout that forwards each call to Blender's and notes the
  text and the share of the width it was given: the property-split label column is 40 %, ``UI_ITEM_PROP_SEP_DIVIDE``
  in Blender's ``interface_layout.cc``; a ``split(factor=f)`` gives its first item f; a row divides its width among
  its items, an icon-only button taking one unit);
* measures each text with Blender's font code (``blf``, the interface font at 11 pt times the interface scale) and
  compares it with the room it has: its share of the panel's layout width less Blender's text clip margins
  (``UI_TEXT_CLIP_MARGIN``, a quarter unit each side) and its icon. The layout width is the region's width less
  :data:`PANEL_INSET_PX` (the panel's margins and the region's scroll bar).

Texts over their room are listed as cut; the script exits with an error if any is, or if a redraw recorded no
text. For scale it also reports whether the labels issue 29 saw cut ("Top Irradiance", "Mie Anisotropy",
"Rayleigh (1/km)") would fit this label column. The results go to ``DIR/panel.json`` and stdout (lines starting
``PANEL``). Blender quits when done, also after an error.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import bpy

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tools"))
sys.dont_write_bytecode = True  # Blender's Python leaves no caches in the checkout

from gui_steps import run_steps  # noqa: E402  (tools/, on the path from here)

#: Region width minus the panel layout's width, px at interface scale 1: two panel margins of 8 px
#: (``style->panelspace``), the sub-panels' inset and the region's scroll bar, together about 2 units.
PANEL_INSET_PX = 40.0
UNIT_PX = 20.0                 # ``U.widget_unit`` at scale 1: an icon, a checkbox, an icon-only button
CLIP_MARGIN_PX = 0.25 * UNIT_PX  # ``UI_TEXT_CLIP_MARGIN``, each side of a button's text
LABEL_COLUMN = 0.4             # ``UI_ITEM_PROP_SEP_DIVIDE``
FONT_POINTS = 11.0             # the interface font's size at scale 1
CUT_IN_ISSUE_29 = ("Top Irradiance", "Mie Anisotropy", "Rayleigh (1/km)")
SETTLE_S = 3.0                 # seconds for a redraw (and Eevee's first shader compile of the preview) to land


# -- a layout that draws in Blender's and notes what it drew ----------------------------------------------------


class Share:
    """A part of the panel's layout width: ``px`` once the whole panel has been drawn (rows are complete)."""

    def __init__(self, fraction: float = 1.0, parent: Share | None = None, row: _Row | None = None, index: int = 0):
        self.fraction, self.parent, self.row, self.index = fraction, parent, row, index

    def px(self, layout_px: float, scale: float) -> float:
        if self.row is not None:
            return self.row.part(self.index, layout_px, scale)
        return self.fraction * (self.parent.px(layout_px, scale) if self.parent else layout_px)


class _Row:
    """A row's items: icon-only ones take one unit, the others equal parts of the rest."""

    def __init__(self, share: Share):
        self.share, self.icon_only = share, []

    def part(self, index: int, layout_px: float, scale: float) -> float:
        unit = UNIT_PX * scale
        if self.icon_only[index]:
            return unit
        rest = self.share.px(layout_px, scale) - unit * sum(self.icon_only)
        return rest / max(len(self.icon_only) - sum(self.icon_only), 1)


class Tee:
    """Stands in for ``UILayout`` in the panels' ``draw``: forwards every call and records each text and its room."""

    def __init__(self, real, record: list, share: Share, row: _Row | None = None, split: float | None = None):
        for name, value in (("_real", real), ("_record", record), ("_share", share), ("_row", row),
                            ("_split", split), ("_placed", 0)):
            object.__setattr__(self, name, value)

    def __getattr__(self, name):
        return getattr(self._real, name)

    def __setattr__(self, name, value):
        setattr(self._real, name, value)

    def _place(self, icon_only: bool = False) -> Share:
        """The share of the next item: a split's first item its factor, the rest the remainder; a row's, a part."""
        placed = self._placed
        object.__setattr__(self, "_placed", placed + 1)
        if self._split is not None:
            return Share(self._split if placed == 0 else 1.0 - self._split, self._share)
        if self._row is not None:
            self._row.icon_only.append(icon_only)
            return Share(row=self._row, index=len(self._row.icon_only) - 1)
        return self._share

    def _note(self, kind: str, text: str, share: Share, icon: bool, column: float = 1.0, units: float = 0.0):
        if text:
            self._record.append({"kind": kind, "text": text, "share": share, "icon": icon, "column": column,
                                 "units": units})

    def _child(self, real, *, row: bool = False, split: float | None = None):
        share = self._place()
        return Tee(real, self._record, share, _Row(share) if row else None, split)

    def row(self, *args, **kwargs):
        return self._child(self._real.row(*args, **kwargs), row=True)

    def column(self, *args, **kwargs):
        return self._child(self._real.column(*args, **kwargs))

    def box(self, *args, **kwargs):
        return self._child(self._real.box(*args, **kwargs))

    def split(self, *args, **kwargs):
        return self._child(self._real.split(*args, **kwargs), split=kwargs.get("factor", args[0] if args else 0.5))

    def prop(self, data, name, **kwargs):
        prop = data.bl_rna.properties[name]
        text = kwargs.get("text")
        label = prop.name if text is None else text
        value_column = (1.0 - LABEL_COLUMN) if self._real.use_property_split else 1.0
        if self._real.use_property_split and prop.type != "BOOLEAN" and not kwargs.get("expand"):
            share = self._place()
            self._note("label", label, share, False, LABEL_COLUMN)   # the label column
            self._note_value(data, prop, kwargs, share, 1.0 - LABEL_COLUMN)
        elif prop.type == "ENUM" and kwargs.get("expand"):
            share = self._place()
            items = [item.name for item in prop.enum_items]
            for item in items:
                self._note("enum item", item, share, False, value_column / len(items))
        else:
            icon = kwargs.get("icon", "NONE") != "NONE" or prop.type == "BOOLEAN"   # a checkbox is a unit wide
            self._note("button", label, self._place(icon_only=not label), icon, value_column)
        return self._real.prop(data, name, **kwargs)

    def _note_value(self, data, prop, kwargs, share: Share, column: float) -> None:
        """The text a value field shows where it is a name, not a number (Blender shortens numbers to fit): a
        pointer's data-block name or its placeholder (after the data-block icon, before the eyedropper), an enum
        menu's current item (before its arrow)."""
        if prop.type == "POINTER":
            value = getattr(data, prop.identifier)
            text = value.name if value is not None else kwargs.get("placeholder", "")
            self._note("value", text, share, True, column, units=1.0)
        elif prop.type == "ENUM" and not prop.is_enum_flag:
            identifier = getattr(data, prop.identifier)
            names = [item.name for item in prop.enum_items if item.identifier == identifier]
            if names:
                self._note("value", names[0], share, True, column)

    def operator(self, idname, **kwargs):
        text = kwargs.get("text")
        if text is None:
            module, name = idname.split(".")
            text = getattr(getattr(bpy.ops, module), name).get_rna_type().name
        self._note("button", text, self._place(icon_only=not text), "icon" in kwargs)
        return self._real.operator(idname, **kwargs)

    def menu(self, menu, **kwargs):
        text = kwargs.get("text", getattr(bpy.types, menu).bl_label)
        self._note("menu", text, self._place(icon_only=not text), True)   # a menu button draws its arrow
        return self._real.menu(menu, **kwargs)

    def label(self, **kwargs):
        self._note("line", kwargs.get("text", ""), self._place(), "icon" in kwargs)
        return self._real.label(**kwargs)


def measure(record: list, layout_px: float, scale: float) -> list[dict]:
    """Each recorded text with its drawn width and its room, px."""
    import blf

    blf.size(0, FONT_POINTS * scale)
    rows = []
    for entry in record:
        room = entry["share"].px(layout_px, scale) * entry["column"]
        room -= 2.0 * CLIP_MARGIN_PX * scale + UNIT_PX * scale * ((1.0 if entry["icon"] else 0.0) + entry["units"])
        width = blf.dimensions(0, entry["text"])[0]
        rows.append({"kind": entry["kind"], "text": entry["text"], "width_px": round(width, 1),
                     "room_px": round(room, 1), "cut": width > room + 0.5})
    return rows


# -- the GUI run ----------------------------------------------------------------------------------------------


def parse_args() -> argparse.Namespace:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="verify_panel.py")
    parser.add_argument("--out", type=Path, required=True, help="folder for the screenshots and panel.json")
    parser.add_argument("--zip", type=Path, help="install this extension zip and check it (default: this checkout)")
    return parser.parse_args(argv)


def properties_area(window):
    return max((a for a in window.screen.areas if a.type == "PROPERTIES"), key=lambda a: a.height)


def screenshot(window, area, path: Path) -> None:
    top = window.height - (area.y + area.height)
    subprocess.run(["import", "-window", "root", "-crop", f"{area.width}x{area.height}+{area.x}+{top}", "+repage",
                    str(path)], check=True, timeout=60)


#: The package Blender loads the extension as when it is installed into the user repository.
EXTENSION_PACKAGE = "bl_ext.user_default.atmos"


def load_atmos(zip_path: Path | None):
    """The ``atmos_addon`` package, registered: installed from ``zip_path`` into the user repository and enabled, as
    Preferences > Get Extensions > Install from Disk does, or from this checkout without a zip."""
    import importlib

    if zip_path is None:
        import atmos_addon

        atmos_addon.register()
        return atmos_addon
    done = bpy.ops.extensions.package_install_files(filepath=str(zip_path), repo="user_default",
                                                    enable_on_install=True)
    if done != {"FINISHED"} or EXTENSION_PACKAGE not in bpy.context.preferences.addons:
        raise RuntimeError(f"installing {zip_path} gave {done}; {EXTENSION_PACKAGE} is not enabled")
    return importlib.import_module(EXTENSION_PACKAGE + ".atmos_addon")


def record_panels(panel, record: list) -> None:
    """Re-register the Atmosphere panels open (also the ones closed by default: every text is drawn) and drawing
    through a :class:`Tee` that notes into ``record``."""
    panels = [cls for cls in panel.CLASSES if issubclass(cls, bpy.types.Panel)]
    for cls in reversed(panels):
        bpy.utils.unregister_class(cls)
    for cls in panels:
        cls.bl_options = set(getattr(cls, "bl_options", ())) - {"DEFAULT_CLOSED"}
        for method in ("draw", "draw_header"):
            if method in cls.__dict__:
                setattr(cls, method, _recording(cls.__dict__[method], record))
        bpy.utils.register_class(cls)


def run(args: argparse.Namespace, result: dict):
    """The whole check into ``result``, as a generator of timer delays."""
    import importlib

    from atmos_addon.sample_scenes import valley

    scene = valley.build()   # reads factory settings (use_empty): first, before anything holds a window
    yield 1.0
    atmos = load_atmos(args.zip)
    result["atmos"] = atmos.__file__
    api = importlib.import_module(atmos.__name__ + ".api")
    panel = importlib.import_module(atmos.__name__ + ".blender.ui.panel")
    record: list = []
    record_panels(panel, record)
    window = bpy.context.window_manager.windows[0]
    window.scene = scene
    area = properties_area(window)
    space = area.spaces.active
    space.context = "WORLD"
    region = next(r for r in area.regions if r.type == "WINDOW")
    scale = bpy.context.preferences.system.ui_scale
    layout_px = region.width - PANEL_INSET_PX * scale
    result.update(region_width_px=region.width, ui_scale=scale, layout_px=layout_px, cases={})
    print(f"PANEL Blender {bpy.app.version_string}: Properties editor {area.width} x {area.height} px, "
          f"region {region.width} px, interface scale {scale}", flush=True)
    eevee = "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"
    for engine in (eevee, "CYCLES"):
        for state in ("on", "off"):
            scene.render.engine = engine
            if state == "on":
                api.enable(scene, preset="clear")
            else:
                api.disable(scene)
            yield SETTLE_S
            record.clear()
            area.tag_redraw()
            yield SETTLE_S
            tag = f"{'eevee' if engine != 'CYCLES' else 'cycles'}_{state}"
            png = args.out / f"panel_{tag}.png"
            screenshot(window, area, png)
            rows = measure(record, layout_px, scale)
            result["cases"][tag] = {"png": png.name, "texts": rows}
            print(f"PANEL {tag}: {len(rows)} texts, {sum(r['cut'] for r in rows)} cut -> {png.name}", flush=True)
            for row in rows:
                if row["cut"]:
                    print(f"PANEL   cut: {row['kind']} {row['text']!r} {row['width_px']} px in {row['room_px']} px",
                          flush=True)
    import blf

    blf.size(0, FONT_POINTS * scale)
    room = LABEL_COLUMN * layout_px - 2.0 * CLIP_MARGIN_PX * scale
    result["issue_29_labels"] = {text: {"width_px": round(blf.dimensions(0, text)[0], 1), "room_px": round(room, 1)}
                                 for text in CUT_IN_ISSUE_29}
    cut = [(tag, row["text"]) for tag, case in result["cases"].items() for row in case["texts"] if row["cut"]]
    if cut:
        result["errors"].append(f"cut at the default width: {cut}")
    if not all(case["texts"] for case in result["cases"].values()):
        result["errors"].append("a redraw recorded no text: the panel was not drawn")


def _recording(function, record: list):
    """``function`` (a panel's draw or draw_header) drawing through a :class:`Tee` that notes into ``record``."""

    def draw(self, context):
        function(_PanelView(self, Tee(self.layout, record, Share())), context)

    return draw


class _PanelView:
    """The panel as its draw function sees it, with the recording layout."""

    def __init__(self, panel, layout):
        self._panel, self.layout = panel, layout

    def __getattr__(self, name):
        return getattr(self._panel, name)


def main() -> None:
    args = parse_args()
    bpy.context.preferences.view.show_splash = False
    args.out.mkdir(parents=True, exist_ok=True)
    result = {"blender": bpy.app.version_string, "errors": []}

    def finish():
        (args.out / "panel.json").write_text(json.dumps(result, indent=1))
        for error in result["errors"]:
            print(f"PANEL ERROR {error}", flush=True)
        print(f"PANEL {'FAILED' if result['errors'] else 'OK'}: wrote {args.out / 'panel.json'}", flush=True)
        # Blender's own exit: it unregisters the add-on's command-line handler and frees Blender's data, where a
        # crash on exit would show (the exit status is then not 0 and the check fails).
        if result["errors"]:
            os._exit(1)
        bpy.ops.wm.quit_blender()

    run_steps(run(args, result), result["errors"], finish, persistent=True)   # valley.build loads a file


main()
