"""The operator is a thin shell over penumbra.bake(): same result, errors reported, not raised."""
import bpy
import pytest

import cornell_box
import helpers


def test_operator_bakes_with_the_panel_settings(empty_scene):
    cornell_box.build()
    s = empty_scene.penumbra
    s.resolution = 24
    s.epsilon = 0.004
    s.color_attribute = False
    assert bpy.ops.penumbra.bake() == {"FINISHED"}
    assert tuple(bpy.data.images["Penumbra_Floor"].size) == (24, 24)
    assert "Penumbra" not in bpy.data.objects["Floor"].data.attributes
    # INVOKE_DEFAULT in the background falls back to execute (no event loop, blender-facts §5).
    assert bpy.ops.penumbra.bake("INVOKE_DEFAULT") == {"FINISHED"}
    assert bpy.ops.penumbra.preview(on=True) == {"FINISHED"}
    assert bpy.ops.penumbra.preview(on=False) == {"FINISHED"}
    assert bpy.ops.penumbra.clear() == {"FINISHED"}
    assert not [i for i in bpy.data.images if i.name.startswith("Penumbra")]


def test_operator_reports_a_failed_bake(empty_scene):
    cornell_box.build()
    empty_scene.penumbra.uv_map = "Missing"
    before = helpers.blend_state()
    # An operator that reports an ERROR raises RuntimeError when called from Python.
    with pytest.raises(RuntimeError, match="UV map 'Missing' is missing on: Floor"):
        bpy.ops.penumbra.bake()
    helpers.assert_same_state(before, helpers.blend_state())
