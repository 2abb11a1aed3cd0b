"""Operators: Bake (modal, the solver in a worker thread), Preview toggle, Clear.

The Bake button runs `penumbra.begin()` (reads the scene) on the main thread, `Job.solve()` in a worker thread
(the native solver releases the GIL; the worker never touches bpy) and `Job.finish()` (write-back) on the main
thread again when the worker is done, inside the operator's one undo step. Esc requests the cancel and ends the
operator at once: nothing has been written, and the worker stops at the solver's next progress check.
In `blender -b`, or without a window, `invoke` runs the same bake synchronously (`execute`): there is no event
loop there to drive a modal operator (blender-facts §5).
"""
import atexit
import json
import os
import threading
import time

import bpy
from bpy.props import BoolProperty

TIMER_STEP = 0.1          # seconds between progress updates of the panel and the status bar

# Where each stage of a bake sits on the overall progress bar, in percent.
_SPANS = {"export": (0, 2), "solve": (2, 4), "visibility": (4, 5), "refine": (5, 50), "gather": (50, 95),
          "write-back": (95, 100), "done": (100, 100)}
_STAGE_TEXT = {"export": "Reading the scene", "solve": "Starting the solver", "visibility": "Building ray "
               "acceleration", "refine": "Subdividing surfaces", "gather": "Bouncing light",
               "write-back": "Writing lightmaps", "done": "Done"}


class Worker:
    """The solve of one bake in a thread; the main thread reads `percent` and `stage` and sets `cancel`."""

    def __init__(self, job):
        self.job = job
        self.cancel = threading.Event()
        self.stage = "solve"
        self.percent = _SPANS["solve"][0]
        self.error = None
        self.started = time.perf_counter()
        self.cancel_requested_at = None
        self.stopped_at = None
        self._seen_refine = False
        self.thread = threading.Thread(target=self._run, name="penumbra-solve", daemon=True)

    def start(self):
        self.thread.start()
        return self

    def progress(self, stage, fraction):
        # Called from the solver's thread with the GIL held: plain attribute updates only, no bpy.
        if stage == "refine":
            self._seen_refine = True
        elif stage == "solve" and self._seen_refine:
            stage = "gather"      # the native "solve" stage after refinement is the bounce iteration
        self.stage = stage
        lo, hi = _SPANS.get(stage, (self.percent, self.percent))
        f = min(max(float(fraction), 0.0), 1.0)
        # Later refinement passes start their stages over; the bar never goes back.
        self.percent = max(self.percent, lo + (hi - lo) * f)
        return not self.cancel.is_set()

    def _run(self):
        try:
            self.job.solve(self.progress)
        except BaseException as e:     # handed to the main thread, which reports it
            self.error = e
        finally:
            self.stopped_at = time.perf_counter()

    def request_cancel(self):
        if self.cancel_requested_at is None:
            self.cancel_requested_at = time.perf_counter()
        self.cancel.set()

    @property
    def done(self):
        return not self.thread.is_alive()


# The modal bake in progress (one at a time), and the workers of cancelled bakes that have not stopped yet.
# Plain Python objects: the operator's own RNA struct is gone once Blender frees the operator.
_running = None           # _Running
_stopping = []


class _Running:
    def __init__(self, operator, worker):
        self.operator = operator
        self.worker = worker


def running_bake():
    """The bake in progress (with .worker and .operator), or None."""
    return _running


def stopping_workers():
    _stopping[:] = [w for w in _stopping if not w.done]
    return list(_stopping)


def _stop_all(timeout=5.0):
    """Cancel every worker and wait for them, so none is left inside the solver when Python shuts down."""
    workers = stopping_workers() + ([_running.worker] if _running is not None else [])
    for w in workers:
        w.request_cancel()
    for w in workers:
        w.thread.join(timeout)


atexit.register(_stop_all)


def _tag_redraw():
    # Only the regions that can show the panel: redrawing whole 3D views ten times a second costs the frame
    # rate that keeps the window responsive (software OpenGL especially).
    wm = bpy.context.window_manager
    for win in wm.windows:
        for area in win.screen.areas:
            if area.type == "PROPERTIES" or (area.type == "VIEW_3D" and area.spaces.active.show_region_ui):
                for region in area.regions:
                    if region.type in ("WINDOW" if area.type == "PROPERTIES" else "UI",):
                        region.tag_redraw()


def _record(context, scene, outcome, message, report=None):
    """The outcome shown under Last Bake. A successful report is also stored on the scene (saved with the file,
    part of the bake's undo step); a failure or cancel only lives in the window manager, so it changes nothing
    in the .blend."""
    rt = context.window_manager.penumbra
    rt.scene = scene.name
    rt.outcome = outcome
    rt.message = message
    rt.report = json.dumps(report) if report is not None else ""
    if report is not None:
        scene.penumbra.last_report = rt.report


def _error_text(e):
    import penumbra
    if isinstance(e, penumbra.Cancelled):
        return "CANCELLED", "Bake cancelled; the scene is unchanged"
    return "ERROR", f"{e}"


class PENUMBRA_OT_bake(bpy.types.Operator):
    bl_idname = "penumbra.bake"
    bl_label = "Bake Radiosity"
    bl_description = ("Compute the scene's bounced diffuse light and store it in lightmaps and color attributes. "
                      "Esc cancels; the scene changes only when the bake succeeds (one undo step)")
    bl_options = {"REGISTER", "UNDO"}

    worker = None

    @classmethod
    def poll(cls, context):
        if _running is not None:
            cls.poll_message_set("A bake is running (Esc cancels it)")
            return False
        s = getattr(context.scene, "penumbra", None)
        if s is not None and not (s.lightmap or s.color_attribute):
            cls.poll_message_set("Choose a target: Lightmap, Color Attribute or both")
            return False
        return True

    def _report_outcome(self, report):
        import penumbra
        for x in report["skipped"]:
            self.report({"WARNING"}, f"skipped {x['name']}: {x['reason']}")
        for w in report["warnings"]:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, penumbra.summary(report))

    def execute(self, context):
        import penumbra
        scene = context.scene
        try:
            report = penumbra.bake(scene, **scene.penumbra.as_settings())
        except Exception as e:  # the bake left the .blend untouched; say why it stopped
            outcome, msg = _error_text(e)
            _record(context, scene, outcome, msg)
            self.report({"WARNING" if outcome == "CANCELLED" else "ERROR"}, f"Penumbra: {msg}")
            return {"CANCELLED"}
        _record(context, scene, "FINISHED", penumbra.summary(report), report)
        self._report_outcome(report)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        import penumbra
        global _running
        scene = context.scene
        settings = scene.penumbra.as_settings()
        if settings["threads"] == 0:
            # All cores but one: the window must keep drawing and answering Esc while the solver runs.
            settings["threads"] = max(1, (os.cpu_count() or 1) - 1)
        try:
            job = penumbra.begin(scene, **settings)
        except Exception as e:
            outcome, msg = _error_text(e)
            _record(context, scene, outcome, msg)
            self.report({"ERROR"}, f"Penumbra: {msg}")
            _tag_redraw()
            return {"CANCELLED"}
        self.scene_name = scene.name
        self.worker = Worker(job).start()
        self._state = _Running(self, self.worker)
        _running = self._state
        wm = context.window_manager
        rt = wm.penumbra
        rt.running, rt.progress, rt.stage, rt.scene = True, 0.0, _STAGE_TEXT["solve"], scene.name
        rt.outcome, rt.message = "", ""
        wm.progress_begin(0, 100)
        self._window = context.window
        self._timer = wm.event_timer_add(TIMER_STEP, window=context.window)
        wm.modal_handler_add(self)
        self._show(context)
        return {"RUNNING_MODAL"}

    def _show(self, context):
        w = self.worker
        wm = context.window_manager
        rt = wm.penumbra
        rt.progress = w.percent
        rt.stage = _STAGE_TEXT.get(w.stage, w.stage)
        wm.progress_update(w.percent)
        elapsed = time.perf_counter() - w.started
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"Penumbra: {rt.stage} {w.percent:.0f} %  ({elapsed:.0f} s)   Esc: cancel")
        _tag_redraw()

    def _end(self, context):
        global _running
        wm = context.window_manager
        if getattr(self, "_timer", None) is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        wm.penumbra.running = False
        if _running is getattr(self, "_state", None):
            _running = None
        _tag_redraw()

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            return self.cancel_bake(context)
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        self._show(context)
        if not self.worker.done:
            return {"PASS_THROUGH"}
        return self._finish(context)

    def cancel_bake(self, context):
        """What Esc does: stop waiting at once; the worker stops at the solver's next progress check and its
        result is dropped. Nothing was written, so there is nothing to undo."""
        self.worker.request_cancel()
        if not self.worker.done:
            _stopping.append(self.worker)
        self._end(context)
        scene = bpy.data.scenes.get(self.scene_name) or context.scene
        _record(context, scene, "CANCELLED", "Bake cancelled; the scene is unchanged")
        self.report({"WARNING"}, "Penumbra: bake cancelled; the scene is unchanged")
        return {"CANCELLED"}

    def cancel(self, context):
        # Blender ends the operator without an event (a file is loaded, the window closes): same as Esc.
        if _running is not None and _running is getattr(self, "_state", None):
            self.cancel_bake(context)

    def _finish(self, context):
        import penumbra
        w = self.worker
        self._end(context)
        scene = bpy.data.scenes.get(self.scene_name)
        if w.error is None and scene is None:
            w.error = penumbra.BakeError(f"the scene '{self.scene_name}' was removed while the bake ran")
        if w.error is None:
            try:
                report = w.job.finish()
            except Exception as e:  # the write-back rolled back: the .blend is as it was
                w.error = e
        if w.error is not None:
            outcome, msg = _error_text(w.error)
            _record(context, scene or context.scene, outcome, msg)
            self.report({"WARNING" if outcome == "CANCELLED" else "ERROR"}, f"Penumbra: {msg}")
            return {"CANCELLED"}
        _record(context, scene, "FINISHED", penumbra.summary(report), report)
        self._report_outcome(report)
        return {"FINISHED"}


def scene_has_bake(scene):
    from .writeback import PROP
    return any(ob.type == "MESH" and ob.get(PROP) is not None for ob in scene.objects)


def scene_preview_on(scene):
    from .preview import STATE
    return any(ob.type == "MESH" and ob.get(STATE) is not None for ob in scene.objects)


class PENUMBRA_OT_preview(bpy.types.Operator):
    bl_idname = "penumbra.preview"
    bl_label = "Preview Bake"
    bl_description = ("Switch the baked objects between showing the bake (an emissive material with the "
                      "lightmap, in the viewport and in renders) and their own materials")
    bl_options = {"REGISTER", "UNDO"}
    on: BoolProperty(name="Show Bake", description="Show the bake (on) or the original materials (off); "
                     "left unset, the operator toggles", default=True)

    @classmethod
    def poll(cls, context):
        if not scene_has_bake(context.scene):
            cls.poll_message_set("Nothing is baked in this scene yet")
            return False
        return _running is None

    def execute(self, context):
        import penumbra
        on = self.on if self.properties.is_property_set("on") else not scene_preview_on(context.scene)
        changed = penumbra.preview(context.scene, on)
        self.report({"INFO"}, f"Penumbra: {'showing the bake' if on else 'showing the original materials'} on "
                              f"{len(changed)} object(s)")
        return {"FINISHED"}


class PENUMBRA_OT_clear(bpy.types.Operator):
    bl_idname = "penumbra.clear"
    bl_label = "Clear Bake"
    bl_description = "Remove the lightmaps, color attributes and UV maps that Penumbra made (undoable)"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _running is None

    def execute(self, context):
        import penumbra
        removed = penumbra.clear(context.scene)
        context.scene.penumbra.last_report = ""
        rt = context.window_manager.penumbra
        if rt.scene == context.scene.name:
            rt.outcome = rt.message = rt.report = ""
        self.report({"INFO"}, f"Penumbra: cleared the bake of {len(removed)} object(s)")
        return {"FINISHED"}


@bpy.app.handlers.persistent
def _forget_outcome(_dummy):
    # The last bake's outcome belongs to the file it was made in; a saved report comes back with its scene.
    wm = bpy.context.window_manager
    if wm is not None and hasattr(wm, "penumbra"):
        rt = wm.penumbra
        rt.running, rt.progress, rt.stage, rt.scene, rt.outcome, rt.message, rt.report = \
            False, 0.0, "", "", "", "", ""


CLASSES = (PENUMBRA_OT_bake, PENUMBRA_OT_preview, PENUMBRA_OT_clear)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.app.handlers.load_post.append(_forget_outcome)


def unregister():
    _stop_all()
    if _forget_outcome in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_forget_outcome)
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
