"""The lightmap UV map both benchmarks bake into (bench/run_time_vs_error.py, bench/validate.py): the same
Smart UV Project for Cycles' reference bake and for Penumbra, so that their texels can be compared one by one."""
import math

import bpy
import numpy as np

UV = "Lightmap"


def unwrap(ob, uv_name=UV):
    """A new UV map on a mesh object, made active, unwrapped by Smart UV Project (66 degrees, margin 0.02)."""
    me = ob.data
    me.uv_layers.active = me.uv_layers.new(name=uv_name)
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    ob.select_set(True)
    vl.objects.active = ob
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.smart_project(angle_limit=math.radians(66), island_margin=0.02, area_weight=0.0,
                             correct_aspect=True, scale_to_bounds=False)
    bpy.ops.object.mode_set(mode="OBJECT")


def uv_array(ob, uv_name=UV):
    """The UV map's coordinates, one (u, v) per loop, flattened."""
    a = np.empty(len(ob.data.loops) * 2, np.float32)
    ob.data.uv_layers[uv_name].data.foreach_get("uv", a)
    return a
