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
    "location": "Properties > Render > Penumbra",
    "description": "Bakes diffuse global illumination with a native hierarchical-radiosity solver",
    "category": "Render",
}

import json
import os
import sys
import time


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


try:
    from . import _native
except ImportError as _e:
    raise ImportError(_native_mismatch(_e)) from _e

from . import export, writeback, preview as _preview  # noqa: E402

Cancelled = getattr(_native, "Cancelled", None)

SOLVER_KEYS = ("epsilon", "min_size", "visibility_rays", "max_iterations", "tolerance", "refine_passes",
               "threads")
TARGETS = frozenset({"LIGHTMAP", "COLOR_ATTRIBUTE"})
DEFAULTS = {"resolution": 256, "margin": 4, "uv_map": None, "targets": TARGETS, "selection_only": False,
            "output_dir": None}


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
    for key, lo, hi in (("resolution", 8, 16384), ("margin", 0, 1024)):
        v = s[key]
        if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
            raise ValueError(f"{key} must be an integer in [{lo}, {hi}], got {v!r}")
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


def bake(scene=None, progress=None, **settings):
    """Solve the scene's diffuse global illumination and store it in every baked object.

    `progress(stage, fraction)` is called during the bake (from the solver's thread while solving, so it must
    not touch bpy); returning False cancels, and `Cancelled` is raised. Nothing in the .blend changes unless
    the bake succeeds. Returns a JSON-serialisable report.
    """
    import bpy
    scene = scene or bpy.context.scene
    s, solver_settings = _settings(settings)
    vl = _view_layer(scene)
    report = {"settings": _jsonable({**s, **solver_settings}), "times": {}, "warnings": [], "notes": [],
              "skipped": []}
    t_start = time.perf_counter()

    def step(stage, frac):
        if progress is not None and progress(stage, frac) is False:
            raise Cancelled(f"cancelled during {stage}") if Cancelled else RuntimeError("cancelled")

    # Export reads evaluated meshes, which do not see edits still held in edit mode.
    edit_obj = bpy.context.edit_object if bpy.context.scene == scene else None
    if edit_obj is not None:
        bpy.ops.object.mode_set(mode="OBJECT")
    try:
        step("export", 0.0)
        t = time.perf_counter()
        ex = export.export_scene(scene, vl, _depsgraph(scene, vl), s["selection_only"])
        report["times"]["export"] = time.perf_counter() - t
        report["skipped"] = ex.skipped
        report["warnings"] += ex.warnings
        report["notes"] += ex.notes
        report["export"] = ex.counts
        if len(ex.polygons) == 0:
            raise BakeError("nothing to bake: the scene has no visible mesh faces or area lights"
                            + (" among the selected objects" if s["selection_only"] else ""))
        if not ex.bake_objects:
            raise BakeError("no object can be baked (visible, non-instanced mesh objects with faces); skipped: "
                            + ", ".join(f"{x['name']} ({x['reason']})" for x in ex.skipped))
        if s["uv_map"]:
            missing = [n for n in ex.bake_objects if s["uv_map"] not in bpy.data.objects[n].data.uv_layers]
            if missing:
                raise BakeError(f"UV map '{s['uv_map']}' is missing on: {', '.join(missing)}")
        if s["output_dir"]:
            os.makedirs(bpy.path.abspath(s["output_dir"]), exist_ok=True)

        step("solve", 0.0)
        t = time.perf_counter()
        cb = None
        if progress is not None:
            def cb(stage, frac):
                return progress(stage, frac) is not False
        solution = _native.solve(ex.vertices, ex.polygons, ex.reflectance, ex.emission, ex.flags,
                                 ex.object_index, ex.object_names, solver_settings, cb)
        report["times"]["solve"] = time.perf_counter() - t
        native_report = _jsonable(dict(solution.report))
        report["solver"] = native_report
        for key in ("polygons", "elements", "leaves", "links", "rays", "iterations", "residual",
                    "refine_passes"):
            if key in native_report:
                report[key] = native_report[key]
        report["warnings"] += [f"solver: {w}" for w in native_report.get("warnings", [])]
        if native_report.get("converged") is False:
            report["warnings"].append(f"solver: not converged after {native_report.get('iterations')} "
                                      f"iterations (residual {_fmt(native_report.get('residual'))}); raise "
                                      f"max_iterations or tolerance")

        step("write-back", 0.0)
        t = time.perf_counter()
        ws = dict(s)
        if ws["output_dir"]:
            ws["output_dir"] = bpy.path.abspath(ws["output_dir"])
        # `step` raises Cancelled when progress says stop, and the write-back then rolls back.
        outputs = writeback.write_all(scene, vl, ex.bake_objects, solution, _native, ws, report,
                                      progress=step if progress is not None else None)
        report["times"]["write_back"] = time.perf_counter() - t
        report["objects_baked"] = list(ex.bake_objects)
        report["outputs"] = outputs
        step("done", 1.0)
    finally:
        if edit_obj is not None and edit_obj.name in bpy.data.objects:
            vl.objects.active = edit_obj
            bpy.ops.object.mode_set(mode="EDIT")
    report["times"]["total"] = time.perf_counter() - t_start
    return _jsonable(report)


def preview(scene, on):
    """Switch every baked object to a material that shows its bake (on) or back to its own materials (off).
    Returns the names of the objects that changed."""
    return _preview.set_preview(scene, bool(on))


def clear(scene):
    """Remove what bakes made in this scene (preview materials, images, attributes, created UV maps)."""
    _preview.set_preview(scene, False)
    return [ob.name for ob in scene.objects if ob.type == "MESH" and writeback.remove_bake(ob)]


def summary(report):
    """One line: time per stage and the solver's counts."""
    t = report.get("times", {})
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in t.items())
    return (f"Penumbra: {len(report.get('objects_baked', []))} objects baked; {stages}; "
            f"{report.get('polygons', '?')} polygons, {report.get('elements', '?')} elements, "
            f"{report.get('links', '?')} links, {report.get('iterations', '?')} iterations, "
            f"residual {_fmt(report.get('residual'))}")


def compare_cycles(scene=None, samples=256, out_dir=None, **options):
    """Compare the bake with Cycles path tracing (camera view, or space="LIGHTMAP"); see compare.py."""
    from . import compare
    return compare.compare_cycles(scene, samples=samples, out_dir=out_dir, **options)


def _fmt(x):
    return f"{x:.2e}" if isinstance(x, (int, float)) else "?"


def register():
    from . import operators, compare
    operators.register()
    compare.register()


def unregister():
    from . import operators, compare
    compare.unregister()
    operators.unregister()
