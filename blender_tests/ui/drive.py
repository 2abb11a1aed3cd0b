"""Drive the Penumbra panel in a real Blender window (run under Xvfb; blender_tests/ui/test_ui_xvfb.py does):

    xvfb-run -a -s "-screen 0 1280x800x24" blender --factory-startup --enable-event-simulate \
        --python blender_tests/ui/drive.py -- --result /tmp/ui.json --screenshot docs/panel.png

Builds the Cornell box, enables the add-on from $PENUMBRA_ADDON_DIR, opens Properties > Render, presses Bake
the way the button does (INVOKE_DEFAULT in the Properties area), watches progress from bpy.app.timers (they
must keep firing while the solver runs), sends Esc through the window's event queue, checks the scene is
unchanged, bakes again to completion, toggles the preview, screenshots the panel, writes the JSON result and
quits. `--enable-event-simulate` is what lets Window.event_simulate() inject the Esc in 3.4 (it also makes
Blender ignore the real keyboard and mouse, which under Xvfb there are none of).
"""
import argparse
import json
import os
import sys
import time
import traceback

import addon_utils
import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "examples"))
sys.path.insert(0, os.path.dirname(HERE))

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--result", default=os.path.join(REPO, "build", "ui_result.json"))
ap.add_argument("--screenshot", default=os.path.join(REPO, "docs", "panel.png"))
# Fine enough that the Cornell box solve runs for many seconds, so there is time to watch it and cancel it.
ap.add_argument("--fine-epsilon", type=float, default=2e-5)
ap.add_argument("--fine-min-size", type=float, default=0.004)
ap.add_argument("--timeout", type=float, default=240.0)
args = ap.parse_args(argv)

result = {"ok": False, "steps": [], "errors": []}
T0 = time.perf_counter()


def log(msg, **data):
    entry = {"t": round(time.perf_counter() - T0, 3), "msg": msg, **data}
    result["steps"].append(entry)
    print(f"drive: {entry}", file=sys.stderr, flush=True)


def write_result():
    os.makedirs(os.path.dirname(os.path.abspath(args.result)), exist_ok=True)
    with open(args.result, "w") as f:
        json.dump(result, f, indent=1)


def _png_is_black(path):
    img = bpy.data.images.load(os.path.abspath(path), check_existing=False)
    try:
        import numpy as np
        px = np.empty(img.size[0] * img.size[1] * img.channels, np.float32)
        img.pixels.foreach_get(px)
        rgb = px.reshape(-1, img.channels)[:, :3]
        return float(rgb.max()) == 0.0
    finally:
        bpy.data.images.remove(img)


def _xvfb_framebuffer_png(xwd_path, png_path):
    """Writes Xvfb's memory framebuffer (an XWD file from `Xvfb -fbdir`, 24-bit TrueColor, 32 bits a pixel)
    as a PNG. False when the file is missing or not in that form."""
    import numpy as np
    try:
        data = open(xwd_path, "rb").read()
    except OSError:
        return False
    hdr = np.frombuffer(data[:100], ">u4")
    header_size, depth, w, h, bits_per_pixel, bytes_per_line, ncolors = (
        int(hdr[0]), int(hdr[3]), int(hdr[4]), int(hdr[5]), int(hdr[11]), int(hdr[12]), int(hdr[19]))
    if depth != 24 or bits_per_pixel != 32:
        return False
    off = header_size + 12 * ncolors
    raw = np.frombuffer(data[off:off + bytes_per_line * h], np.uint8)
    if raw.size != bytes_per_line * h:
        return False
    bgrx = raw.reshape(h, bytes_per_line)[:, :4 * w].reshape(h, w, 4)
    rgba = np.empty((h, w, 4), np.float32)
    rgba[..., 0], rgba[..., 1], rgba[..., 2] = bgrx[..., 2], bgrx[..., 1], bgrx[..., 0]
    rgba[..., :3] /= 255.0
    rgba[..., 3] = 1.0
    img = bpy.data.images.new("penumbra_xvfb_shot", w, h, alpha=False)
    try:
        img.pixels.foreach_set(rgba[::-1].ravel())   # Blender's rows run bottom to top
        img.filepath_raw = os.path.abspath(png_path)
        img.file_format = "PNG"
        img.save()
    finally:
        bpy.data.images.remove(img)
    return True


# --------------------------------------------------------------------------------------------- set-up
bpy.context.preferences.view.show_splash = False       # the splash would cover the window in the screenshot
addon_dir = os.environ.get("PENUMBRA_ADDON_DIR", os.path.join(REPO, "build", "addon"))
sys.path.insert(0, addon_dir)
if addon_utils.enable("penumbra", default_set=True) is None:
    result["errors"].append(f"the add-on did not enable from {addon_dir}")
import cornell_box  # noqa: E402
import helpers  # noqa: E402

for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob)
cornell_box.build()
result["background"] = bpy.app.background


def ui_context():
    """The window, the Properties area showing Render, and its main region: where the Bake button lives."""
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "PROPERTIES")
    area.spaces.active.context = "RENDER"
    region = next(r for r in area.regions if r.type == "WINDOW")
    return {"window": win, "screen": win.screen, "area": area, "region": region}


def view3d_context():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    region = next(r for r in area.regions if r.type == "WINDOW")
    return {"window": win, "screen": win.screen, "area": area, "region": region}


# Timers that keep firing while the solver runs are the evidence that the UI is not blocked.
beats = []


def heartbeat():
    beats.append(time.perf_counter())
    return 0.05


def max_gap(t_from, t_to):
    ts = [t for t in beats if t_from <= t <= t_to]
    if len(ts) < 2:
        return None
    return max(b - a for a, b in zip(ts, ts[1:]))


def script():
    """The test, one step per yield; the value is the delay before the next step."""
    import penumbra
    from penumbra import operators
    ctx = ui_context()
    s = bpy.context.scene.penumbra
    rt = bpy.context.window_manager.penumbra
    s.resolution = 64
    s.epsilon = args.fine_epsilon
    s.min_size = args.fine_min_size
    log("settings", quality=s.quality, epsilon=s.epsilon, min_size=s.min_size)
    # The undo step the bake's must follow: the box as built (startup's own step is the default cube).
    with bpy.context.temp_override(**ctx):
        bpy.ops.ed.undo_push(message="Cornell box")
    # The same window with no bake running, redrawing the Properties editor as often as a bake does: how fast
    # this machine's software OpenGL answers at all, to compare the gaps during the solve with.
    t_idle = time.perf_counter()
    while time.perf_counter() - t_idle < 2.0:
        ctx["area"].tag_redraw()
        yield 0.1
    result["ui_max_gap_idle"] = max_gap(t_idle, time.perf_counter())
    before = helpers.blend_state()

    # ---- first bake: watch progress, then Esc
    with bpy.context.temp_override(**ctx):
        r = bpy.ops.penumbra.bake("INVOKE_DEFAULT")
    log("invoke", ret=sorted(r))
    result["first_invoke"] = sorted(r)
    t_start = time.perf_counter()
    samples = []
    while True:
        yield 0.1
        samples.append((round(time.perf_counter() - t_start, 2), round(rt.progress, 2), rt.stage,
                        operators.running_bake() is not None))
        advanced = len({p for _, p, _, _ in samples}) >= 3
        if operators.running_bake() is None or (advanced and time.perf_counter() - t_start > 2.0):
            break
        if time.perf_counter() - t_start > 60:
            break
    result["progress_samples"] = samples
    result["running_before_esc"] = operators.running_bake() is not None
    running = operators.running_bake()
    worker = running.worker if running is not None else None
    t_esc = time.perf_counter()
    result["ui_max_gap_during_solve"] = max_gap(t_start, t_esc)
    win = ctx["window"]
    try:
        win.event_simulate(type="ESC", value="PRESS")
        win.event_simulate(type="ESC", value="RELEASE")
        result["esc_via"] = "event_simulate"
    except Exception as e:      # Blender started without --enable-event-simulate: call what Esc calls
        log("event_simulate failed; calling the Esc path directly", error=str(e))
        result["esc_via"] = "cancel_bake"
        if running is not None:
            with bpy.context.temp_override(**ctx):
                running.operator.cancel_bake(bpy.context)
    while operators.running_bake() is not None and time.perf_counter() - t_esc < 10:
        yield 0.02
    result["esc_to_operator_end"] = time.perf_counter() - t_esc
    result["outcome_after_esc"] = rt.outcome
    log("after esc", outcome=rt.outcome, running=operators.running_bake() is not None)
    try:
        helpers.assert_same_state(before, helpers.blend_state())
        result["scene_unchanged_after_cancel"] = True
    except AssertionError as e:
        result["scene_unchanged_after_cancel"] = False
        result["errors"].append(f"scene changed by the cancelled bake: {e}")
    result["last_report_after_cancel"] = bpy.context.scene.penumbra.last_report
    # The worker stops at the solver's next progress check; record how long that took.
    while worker is not None and not worker.done and time.perf_counter() - t_esc < 120:
        yield 0.1
    if worker is not None:
        result["worker_stop_after_esc"] = (worker.stopped_at - t_esc) if worker.stopped_at else None
        result["worker_error"] = type(worker.error).__name__ if worker.error else None
    log("worker stopped", after=result.get("worker_stop_after_esc"))

    # ---- second bake, to completion, with the preset the panel starts with
    s.quality = "HIGH"
    s.resolution = 128
    with bpy.context.temp_override(**ctx):
        r = bpy.ops.penumbra.bake("INVOKE_DEFAULT")
    result["second_invoke"] = sorted(r)
    t2 = time.perf_counter()
    while operators.running_bake() is not None and time.perf_counter() - t2 < 120:
        yield 0.1
    result["second_outcome"] = rt.outcome
    result["second_message"] = rt.message
    result["images"] = sorted(i.name for i in bpy.data.images if i.name.startswith("Penumbra_"))
    result["floor_image_size"] = list(bpy.data.images["Penumbra_Floor"].size) \
        if "Penumbra_Floor" in bpy.data.images else None
    result["saved_report"] = bool(bpy.context.scene.penumbra.report())
    log("second bake", outcome=rt.outcome, seconds=time.perf_counter() - t2)

    # ---- one undo step holds the whole bake: undo brings back the unbaked box, redo the bake
    with bpy.context.temp_override(**ctx):
        bpy.ops.ed.undo()
    yield 0.3
    try:
        helpers.assert_same_state(before, helpers.blend_state())
        result["undo_restores_unbaked"] = True
    except AssertionError as e:
        result["undo_restores_unbaked"] = False
        result["errors"].append(f"undo after the bake did not restore the unbaked scene: {e}")
    with bpy.context.temp_override(**ctx):
        bpy.ops.ed.redo()
    yield 0.3
    result["redo_images"] = sorted(i.name for i in bpy.data.images if i.name.startswith("Penumbra_"))

    # ---- preview toggle
    with bpy.context.temp_override(**ctx):
        r1 = bpy.ops.penumbra.preview("INVOKE_DEFAULT")
    result["preview_on"] = operators.scene_preview_on(bpy.context.scene)
    with bpy.context.temp_override(**ctx):
        bpy.ops.penumbra.preview("INVOKE_DEFAULT")
    result["preview_off"] = not operators.scene_preview_on(bpy.context.scene)
    with bpy.context.temp_override(**ctx):
        bpy.ops.penumbra.preview("INVOKE_DEFAULT")
    result["preview_toggle_ret"] = sorted(r1)

    # ---- screenshot: the viewport shows the preview, the Properties editor the panel
    v3d = view3d_context()
    v3d["area"].spaces.active.shading.type = "MATERIAL"
    v3d["area"].spaces.active.overlay.show_overlays = False
    with bpy.context.temp_override(**v3d):
        bpy.ops.view3d.view_camera()
    _show_panel(ctx)
    yield 12.0     # Eevee compiles the preview's shaders in the background
    os.makedirs(os.path.dirname(os.path.abspath(args.screenshot)), exist_ok=True)
    with bpy.context.temp_override(**ctx):
        bpy.ops.screen.screenshot(filepath=os.path.abspath(args.screenshot))
    result["screenshot_source"] = "blender"
    if _png_is_black(args.screenshot):
        # Blender 5.x under Xvfb + llvmpipe reads its own window back as black although the window is drawn
        # (the X framebuffer holds it): take what the X server shows instead.
        fb = os.environ.get("PENUMBRA_XVFB_FBDIR")
        if fb and _xvfb_framebuffer_png(os.path.join(fb, "Xvfb_screen0"), args.screenshot):
            result["screenshot_source"] = "xvfb framebuffer"
    result["screenshot"] = os.path.abspath(args.screenshot)
    log("screenshot", path=result["screenshot"])
    result["ok"] = not result["errors"]


def _show_panel(ctx):
    """Widen the Properties editor (drag the edges the way a user would) and scroll the panel into view."""
    win = ctx["window"]
    area = ctx["area"]
    with bpy.context.temp_override(window=win, screen=win.screen):
        # The vertical edge left of the Properties editor, then the edge between Outliner and Properties.
        bpy.ops.screen.area_move(x=area.x, y=area.y + area.height // 2, delta=-(380 - 0))
        bpy.ops.screen.area_move(x=area.x + area.width // 2, y=area.y + area.height + 1, delta=160)
    with bpy.context.temp_override(**ctx):
        for _ in range(60):
            bpy.ops.view2d.scroll_down(deltay=40)


gen = None


def step():
    global gen
    try:
        if gen is None:
            gen = script()
        return next(gen)
    except StopIteration:
        pass
    except Exception:
        result["errors"].append(traceback.format_exc())
    write_result()
    bpy.app.timers.register(quit_blender, first_interval=0.2)
    return None


def quit_blender():
    bpy.ops.wm.quit_blender()
    return None


def watchdog():
    result["errors"].append(f"timed out after {args.timeout} s")
    write_result()
    os._exit(3)


bpy.app.timers.register(heartbeat, first_interval=0.5, persistent=True)
bpy.app.timers.register(step, first_interval=2.0)
bpy.app.timers.register(watchdog, first_interval=args.timeout)
