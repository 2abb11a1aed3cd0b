"""Penumbra: hierarchical-radiosity global illumination baked into float lightmaps and color attributes.

Python API (once the add-on is enabled, `import penumbra`):
    report = penumbra.bake(scene, progress=None, **settings)
    penumbra.preview(scene, on)
    penumbra.clear(scene)
    figures = penumbra.compare_cycles(scene, samples=256, out_dir=None)
See docs/addon.md for the settings and the report.
"""
bl_info = {
    "name": "Penumbra",
    "author": "Penumbra developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Penumbra; 3D View > Sidebar > Penumbra",
    "description": "Bakes diffuse global illumination with a native hierarchical-radiosity solver",
    "category": "Render",
}

import json
import os
import sys
import time

import numpy as np


def _native_mismatch(err):
    here = os.path.dirname(os.path.abspath(__file__))
    built = "unknown (no _build_info.json next to the add-on)"
    try:
        with open(os.path.join(here, "_build_info.json")) as f:
            built = json.load(f).get("python", built)
    except (OSError, ValueError):
        pass
    running = sys.version.split()[0]
    return (f"Penumbra's native module could not be loaded ({err}). It was built for Python {built}; this "
            f"Blender runs Python {running} ({sys.version}). Rebuild it against the Python this Blender embeds "
            f"(bash scripts/build.sh, or cmake -DPython_EXECUTABLE=<that python>).")


# Installed as a 4.2+ extension this package is bl_ext.<repository>.penumbra; the documented API (and the
# operators' own late imports) say `import penumbra`, so that name is made to point here too.
if __name__ != "penumbra" and "penumbra" not in sys.modules:
    sys.modules["penumbra"] = sys.modules[__name__]

try:
    from . import _native
except ImportError as _e:
    raise ImportError(_native_mismatch(_e)) from _e

from . import export, settings_table, writeback, preview as _preview  # noqa: E402

Cancelled = _native.Cancelled

# The solver settings bake() takes, from the one table of settings (settings_table.py).
SOLVER_KEYS = settings_table.SOLVER_KEYS
TARGETS = frozenset({"LIGHTMAP", "COLOR_ATTRIBUTE"})
# The native solver's default memory guard, max_texels, is 8192 x 8192 per lightmap (about 60 bytes a texel
# while baking, 4 GB at this size); a larger resolution would only be refused after the whole solve.
MAX_RESOLUTION = 8192
DEFAULTS = {"resolution": 256, "margin": 4, "uv_map": None, "targets": TARGETS, "selection_only": False,
            "output_dir": None, "irradiance": False, "instance_lightmaps": False, "patch_texels": 0.0}
# patch_texels > 0: a face that gets a lightmap is cut no finer than that many of its lightmap's texels
# (export.element_floor), instead of min_size times the scene's diagonal. Off by default: on the examples
# at 128 x 128 (docs/scaling.md, "Smallest patch in texels") 1 texel bought 0.2 points of per-texel error
# on the classroom for 2.5x the time, and 2 texels lost 1.6 points on the 5k office (its room is one object,
# so its texels are coarse). It is for what min_size cannot do: a hall or a large plane whose lightmaps
# are finer than 1 % of the scene, and a scene whose diagonal is set by one far object.


class BakeError(RuntimeError):
    """A bake that could not run; the message names the object or setting at fault."""


def _settings(given):
    unknown = sorted(set(given) - set(DEFAULTS) - set(SOLVER_KEYS))
    if unknown:
        raise TypeError(f"unknown Penumbra setting(s): {', '.join(unknown)}; known: "
                        f"{', '.join(sorted(set(DEFAULTS) | set(SOLVER_KEYS)))}")
    s = dict(DEFAULTS)
    s.update({k: v for k, v in given.items() if k in DEFAULTS and v is not None})
    s["targets"] = frozenset(s["targets"] if not isinstance(s["targets"], str) else {s["targets"]})
    if not s["targets"] or not s["targets"] <= TARGETS:
        raise ValueError(f"targets must be a non-empty subset of {sorted(TARGETS)}, got {sorted(s['targets'])}")
    for key in ("selection_only", "irradiance", "instance_lightmaps"):
        if not isinstance(s[key], bool):
            raise TypeError(f"{key} must be True or False, got {s[key]!r}")
    for key in ("uv_map", "output_dir"):
        if s[key] is not None and not isinstance(s[key], str):
            raise TypeError(f"{key} must be a string or None, got {s[key]!r}")
    for key, lo, hi in (("resolution", 8, MAX_RESOLUTION), ("margin", 0, 1024)):
        v = s[key]
        if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
            raise ValueError(f"{key} must be an integer in [{lo}, {hi}], got {v!r}")
    v = s["patch_texels"]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 64:
        raise ValueError(f"patch_texels must be a number in [0, 64] (0: off), got {v!r}")
    s["patch_texels"] = float(v)
    solver = {k: given[k] for k in SOLVER_KEYS if given.get(k) is not None}
    return s, solver


def _jsonable(v):
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, set, frozenset)):
        return [_jsonable(x) for x in (sorted(v) if isinstance(v, (set, frozenset)) else v)]
    if hasattr(v, "item") and callable(v.item):
        return v.item()
    if isinstance(v, float) and v != v:
        return None
    return v


def _view_layer(scene):
    import bpy
    if bpy.context.scene == scene and bpy.context.view_layer is not None:
        return bpy.context.view_layer
    return scene.view_layers[0]


def _depsgraph(scene, vl):
    import bpy
    if bpy.context.scene == scene and bpy.context.view_layer == vl:
        return bpy.context.evaluated_depsgraph_get()
    vl.update()
    return vl.depsgraph


class Job:
    """One bake in three steps, so that the solve can run in a worker thread while Blender stays responsive:

        job = penumbra.begin(scene, **settings)   # main thread: read the scene (bpy)
        job.solve(progress)                       # any thread: the native solve, never touches bpy
        report = job.finish(progress)             # main thread: write the results into the .blend

    `bake()` runs the three in a row. Nothing in the .blend changes before `finish`, and `finish` is
    all-or-nothing; a job that is never finished leaves the scene as it was.
    """

    def __init__(self, scene, view_layer, settings, solver_settings, exported, report, t_start):
        self.scene_name = scene.name
        self.view_layer_name = view_layer.name
        self.settings = settings
        self.solver_settings = solver_settings
        self.exported = exported
        self.report = report
        self.solution = None
        self._t_start = t_start

    def solve(self, progress=None):
        """Run the native solver; safe in a worker thread. Raises `Cancelled` when progress returns False."""
        ex, report = self.exported, self.report
        if progress is not None and progress("solve", 0.0) is False:
            raise Cancelled("cancelled during solve")
        t = time.perf_counter()
        cb = None
        if progress is not None:
            def cb(stage, frac):
                return progress(stage, frac) is not False
        floor = None
        if "LIGHTMAP" in self.settings["targets"] and self.settings["patch_texels"] > 0:
            floor = export.element_floor(ex, self.settings["resolution"], self.settings["patch_texels"])
        solution = _native.solve(ex.vertices, ex.polygons, ex.reflectance, ex.emission, ex.flags,
                                 ex.object_index, ex.object_names, self.solver_settings, cb, ex.lights,
                                 min_edge=floor)
        report["times"]["solve"] = time.perf_counter() - t
        native_report = _jsonable(dict(solution.report))
        report["solver"] = native_report
        # Every count and figure of the solver's report at the top level (the solver declares them,
        # native/src/util/counters.h); its timings and warnings are merged below.
        for key, value in native_report.items():
            if key not in ("times", "warnings", "converged"):
                report[key] = value
        report["warnings"] += [f"solver: {w}" for w in native_report.get("warnings", [])]
        if native_report.get("converged") is False:
            report["warnings"].append(f"solver: not converged after {native_report.get('iterations')} "
                                      f"iterations (residual {_fmt(native_report.get('residual'))}); raise "
                                      f"max_iterations or tolerance")
        self.solution = solution
        return self

    def _black_objects(self):
        ex = self.exported
        if not len(ex.reflectance):
            return set()
        peak = np.zeros(len(ex.object_names))
        np.maximum.at(peak, ex.object_index, ex.reflectance.max(axis=1))
        return {n for n, p in zip(ex.object_names, peak) if p <= 0}

    def finish(self, progress=None):
        """Write the solved bake into the scene (main thread); all or nothing. Returns the report."""
        import bpy
        if self.solution is None:
            raise BakeError("finish() needs a solved job: call solve() first")
        scene = bpy.data.scenes.get(self.scene_name)
        if scene is None:
            raise BakeError(f"the scene '{self.scene_name}' was removed while the bake ran")
        vl = scene.view_layers.get(self.view_layer_name) or _view_layer(scene)
        objs = {}
        for o in bpy.data.objects:      # one walk: `name in bpy.data.objects` walks them all for every name
            objs.setdefault(o.name, o)
        gone = [n for n in self.exported.bake_objects if n not in objs]
        if gone:
            raise BakeError(f"object(s) removed or renamed while the bake ran: {', '.join(gone)}; bake again")
        report, s = self.report, self.settings
        step = _stepper(progress)
        t = time.perf_counter()

        def before_commit(baked, outputs):
            # The last stage reports before anything is committed: a cancel or an error raised at "done"
            # still leaves the .blend and the output folder as they were.
            report["times"]["write_back"] = time.perf_counter() - t
            report["objects_baked"] = list(baked)
            report["outputs"] = outputs
            report["times"]["total"] = time.perf_counter() - self._t_start
            step("done", 1.0)

        # A preview built for another kind of bake (irradiance or not, the lightmap UVs read from the UV map,
        # the modifier copies' attribute or instance tiles) would show the new one wrongly.
        def kind(ob):
            st = writeback.baked_state(ob)
            return bool(st.get("irradiance")), st.get("uv_attribute", ""), bool(st.get("tiles"))
        shown = {n: kind(objs[n]) for n in self.exported.bake_objects if objs[n].get(_preview.STATE) is not None}
        with _object_mode(scene, vl), export.render_visibility(scene, vl):
            step("write-back", 0.0)
            ws = dict(s)
            if ws["output_dir"]:
                ws["output_dir"] = _output_dir(ws["output_dir"])
            # `step` raises Cancelled when progress says stop, and the write-back then rolls back.
            writeback.write_all(scene, vl, self.exported.bake_objects, self.solution, _native, ws, report,
                                progress=step if progress is not None else None, before_commit=before_commit,
                                black=self._black_objects(), two_sided=self.exported.two_sided,
                                instances=self.exported.instances, instance_only=self.exported.instance_only)
        for name, was in shown.items():
            ob = bpy.data.objects[name]
            if name in report.get("objects_baked", ()) and was != kind(ob):
                _preview.preview_off(ob)
                _preview.preview_on(ob)
        return _jsonable(report)


def _output_dir(path):
    """The absolute output folder; a '//' path needs a saved .blend to be relative to."""
    import bpy
    if path.startswith("//") and not bpy.data.filepath:
        raise BakeError(f"output_dir '{path}' is relative to the .blend file, which has not been saved yet: "
                        f"save the file first or give an absolute folder")
    out = os.path.abspath(bpy.path.abspath(path))
    if os.path.exists(out) and not os.path.isdir(out):
        raise BakeError(f"output_dir '{out}' is a file, not a folder")
    return out


def _stepper(progress):
    def step(stage, frac):
        if progress is not None and progress(stage, frac) is False:
            raise Cancelled(f"cancelled during {stage}")
    return step


class _object_mode:
    """Export and write-back read and write mesh data, which edit mode holds back; leave it meanwhile."""

    def __init__(self, scene, vl):
        self.scene, self.vl, self.edit_obj = scene, vl, None

    def __enter__(self):
        import bpy
        self.edit_obj = bpy.context.edit_object if bpy.context.scene == self.scene else None
        if self.edit_obj is not None:
            bpy.ops.object.mode_set(mode="OBJECT")
        return self

    def __exit__(self, *exc):
        import bpy
        if self.edit_obj is not None and self.edit_obj.name in bpy.data.objects:
            self.vl.objects.active = self.edit_obj
            bpy.ops.object.mode_set(mode="EDIT")
        return False


def _opted_out(ob):
    # Reading ob.penumbra_settings creates the group on the object, and a bake must not change objects it does
    # not write to: look first whether it is set. (3.x also showed it as ob["penumbra_settings"]; 5.0 does not.)
    if not ob.is_property_set("penumbra_settings"):
        return False
    return not ob.penumbra_settings.bake


def begin(scene=None, progress=None, **settings):
    """Read the scene and check that it can be baked (main thread). Returns a `Job` to solve and finish.

    Raises `BakeError` with a message naming what to fix (no mesh, no light, ...), TypeError or ValueError
    for bad settings."""
    import bpy
    scene = scene or bpy.context.scene
    s, solver_settings = _settings(settings)
    vl = _view_layer(scene)
    report = {"settings": _jsonable({**s, **solver_settings}), "times": {}, "warnings": [], "notes": [],
              "skipped": []}
    t_start = time.perf_counter()
    step = _stepper(progress)
    if s["output_dir"]:
        _output_dir(s["output_dir"])          # a bad folder is refused before the solve, not after it
    if bpy.context.scene != scene and bpy.context.window is None and "LIGHTMAP" in s["targets"] \
            and not s["uv_map"]:
        raise BakeError(f"the scene '{scene.name}' is not the active scene and there is no window to switch "
                        f"to it for unwrapping the lightmap UVs: make it the active scene, or name an existing "
                        f"UV map with the uv_map setting")
    with _object_mode(scene, vl), export.render_visibility(scene, vl):
        step("export", 0.0)
        t = time.perf_counter()
        ex = export.export_scene(scene, vl, _depsgraph(scene, vl), s["selection_only"],
                                 instance_lightmaps=s["instance_lightmaps"])
        report["times"]["export"] = time.perf_counter() - t
        # Opted-out objects still cast and reflect light; they only get no lightmap or attribute.
        for name in [n for n in ex.bake_objects if _opted_out(bpy.data.objects[n])]:
            ex.bake_objects.remove(name)
            ex.skip(name, "not baked: 'Bake' is off in its Object Properties > Penumbra (it still casts and "
                          "reflects light)")
        if "LIGHTMAP" in s["targets"]:
            for name in _uv_dropped(scene, vl, ex.bake_objects, s["uv_map"] or writeback.UV_NAME):
                ex.bake_objects.remove(name)
                reason = (f"not baked: its modifiers do not keep the UV map '{s['uv_map'] or writeback.UV_NAME}'"
                          f" (geometry nodes that build new geometry, Remesh, ... drop it); it still casts and "
                          f"reflects light")
                ex.skip(name, reason)
                ex.warnings.append(f"object '{name}': {reason}")
        used = [v.name for v in scene.view_layers if v.use]
        if len(used) > 1:
            # Cycles renders every enabled view layer on its own; one bake can match only one of them.
            ex.notes.append(f"baked what view layer '{vl.name}' shows; the scene has {len(used)} view layers "
                            f"({', '.join(used)}) and objects excluded or hidden in '{vl.name}' are left out")
        report["skipped"] = ex.skipped
        report["warnings"] += ex.warnings
        report["notes"] += ex.notes
        report["export"] = ex.counts
        where = " among the selected objects" if s["selection_only"] else ""
        if len(ex.polygons) == 0:
            raise BakeError("nothing to bake: the scene has no visible mesh faces or area lights" + where
                            + _skipped_text(ex.skipped))
        if not ex.bake_objects:
            raise BakeError("no object can be baked (visible, non-instanced mesh objects with faces)" + where
                            + _skipped_text(ex.skipped))
        if not (ex.emission > 0).any() and not ex.lights:
            lights = [x for x in ex.skipped if "light" in x["reason"] or "world" in x["reason"]]
            raise BakeError("nothing emits light" + where + ": add a light (area, point, spot or sun), a world "
                            "colour, or a material with an Emission shader or Principled Emission above zero"
                            + (" (not supported: " + ", ".join(f"{x['name']}: {x['reason']}" for x in lights)
                               + ")" if lights else ""))
        if s["uv_map"]:
            missing = [n for n in ex.bake_objects if s["uv_map"] not in bpy.data.objects[n].data.uv_layers]
            if missing:
                raise BakeError(f"UV map '{s['uv_map']}' is missing on: {', '.join(missing)}")
    return Job(scene, vl, s, solver_settings, ex, report, t_start)


def _uv_dropped(scene, vl, names, uv_name):
    """The objects whose modifiers would lose the lightmap UV map, found before the solve rather than after
    it. A UV map the bake would create is added for the check and removed again."""
    import bpy
    candidates = [bpy.data.objects[n] for n in names if len(bpy.data.objects[n].modifiers)]
    if not candidates:
        return []
    added, checked = [], []
    try:
        for ob in candidates:
            me = ob.data
            if uv_name not in me.uv_layers:
                if len(me.uv_layers) >= 8 or me.library is not None:
                    continue           # cannot try; the write-back reports it if it comes to that
                me.uv_layers.new(name=uv_name, do_init=False)
                me.update_tag()
                added.append(me.name_full)
            checked.append(ob)
        dg = _depsgraph(scene, vl)
        lost = []
        for ob in checked:
            ob_eval = ob.evaluated_get(dg)
            me = ob_eval.to_mesh()
            try:
                if uv_name not in me.uv_layers:
                    lost.append(ob.name)
            finally:
                ob_eval.to_mesh_clear()
        return lost
    finally:
        for mesh_name in added:
            me = bpy.data.meshes.get(mesh_name)
            if me is not None and uv_name in me.uv_layers:
                me.uv_layers.remove(me.uv_layers[uv_name])
                me.update_tag()


def _skipped_text(skipped):
    return ("; skipped: " + ", ".join(f"{x['name']} ({x['reason']})" for x in skipped)) if skipped else ""


def bake(scene=None, progress=None, **settings):
    """Solve the scene's diffuse global illumination and store it in every baked object.

    `progress(stage, fraction)` is called during the bake (from the solver's thread while solving, so it must
    not touch bpy); returning False cancels, and `Cancelled` is raised. Nothing in the .blend changes unless
    the bake succeeds. Returns a JSON-serialisable report.
    """
    import bpy
    scene = scene or bpy.context.scene
    # One mode switch for the whole bake; the inner ones in begin() and finish() then have nothing to do.
    with _object_mode(scene, _view_layer(scene)):
        return begin(scene, progress, **settings).solve(progress).finish(progress)


def preview(scene, on):
    """Switch every baked object to a material that shows its bake (on) or back to its own materials (off).
    Returns the names of the objects that changed."""
    return _preview.set_preview(scene, bool(on))


def clear(scene):
    """Remove what bakes made in this scene (preview materials, images, attributes, created UV maps), and
    Penumbra's own images that no object's bake refers to any more (their object was deleted)."""
    _preview.set_preview(scene, False)
    cleared = [ob.name for ob in list(scene.objects) + _preview.instanced_only(scene)
               if ob.type == "MESH" and writeback.remove_bake(ob)]
    writeback.remove_orphan_images()
    return cleared


def summary(report):
    """One line: time per stage and the solver's counts."""
    t = report.get("times", {})
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in t.items())
    return (f"Penumbra: {len(report.get('objects_baked', []))} objects baked; {stages}; "
            f"{report.get('polygons', '?')} polygons, {report.get('elements', '?')} elements, "
            f"{report.get('links', '?')} links, {report.get('convolution_links', '?')} convolution links "
            f"(of {report.get('convolution_tried', '?')} tried), {report.get('iterations', '?')} iterations, "
            f"residual {_fmt(report.get('residual'))}")


def compare_cycles(scene=None, samples=256, out_dir=None, **options):
    """Compare the bake with Cycles path tracing (camera view, or space="LIGHTMAP"); see compare.py."""
    from . import compare
    return compare.compare_cycles(scene, samples=samples, out_dir=out_dir, **options)


def _fmt(x):
    return f"{x:.2e}" if isinstance(x, (int, float)) else "?"


def register():
    from . import properties, operators, panels, compare
    properties.register()
    operators.register()
    panels.register()
    compare.register()


def unregister():
    from . import properties, operators, panels, compare
    compare.unregister()
    panels.unregister()
    operators.unregister()
    properties.unregister()
    if __name__ != "penumbra" and sys.modules.get("penumbra") is sys.modules.get(__name__):
        del sys.modules["penumbra"]
