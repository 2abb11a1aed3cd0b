"""Numerical stability through penumbra.bake: scale and offset invariance, albedo near 1, slivers, contact, leaks."""
import math

import bpy
import numpy as np
import pytest
from mathutils import Matrix

import cornell_box
import scenes
from helpers import image_pixels
from penumbra import compat

RES = 48


def face_averages(report):
    from penumbra.compare import face_means, uv_owner
    out = {}
    for name in cornell_box.RECEIVERS:
        ob = bpy.data.objects[name]
        img = bpy.data.images[report["outputs"][name]["image"]]
        w, h = img.size
        owner = uv_owner(ob.data, ob["penumbra"]["uv_map"], w, h)
        means, count = face_means(image_pixels(img), owner, len(ob.data.polygons))
        out[name] = means[count > 0]
    return out


@pytest.mark.parametrize("label,matrix", [
    ("scaled 1e-3", Matrix.Scale(1e-3, 4)),
    ("scaled 1e3", Matrix.Scale(1e3, 4)),
    ("moved 1e5", Matrix.Translation((1e5, 0.0, 0.0))),
])
def test_scale_and_offset_invariance(empty_scene, penumbra, label, matrix):
    """The lamp is an emissive mesh: its radiance does not depend on its size, so neither does the bake."""
    cornell_box.build()
    offset = np.array(matrix.translation)
    if offset.any():
        # Vertices are float32 (as Blender stores them and the solver takes them): 1e5 away the grid is 7.8 mm.
        # Snap the box onto that grid first, so both bakes see the same geometry and only the solver's own
        # arithmetic can differ.
        for ob in empty_scene.objects:
            if ob.type == "MESH":
                co = np.empty(len(ob.data.vertices) * 3, np.float32)
                ob.data.vertices.foreach_get("co", co)
                snapped = (co.astype(np.float64).reshape(-1, 3) + offset).astype(np.float32) - offset
                ob.data.vertices.foreach_set("co", snapped.astype(np.float32).ravel())
                ob.data.update()
    base = face_averages(penumbra.bake(empty_scene, resolution=RES, targets={"LIGHTMAP"}))
    for ob in empty_scene.objects:
        ob.matrix_world = matrix @ ob.matrix_world
    rep = penumbra.bake(empty_scene, resolution=RES, targets={"LIGHTMAP"})
    moved = face_averages(rep)
    b = np.concatenate([base[n] for n in cornell_box.RECEIVERS])
    m = np.concatenate([moved[n] for n in cornell_box.RECEIVERS])
    assert np.isfinite(m).all()
    rel = float(np.sqrt(((m - b) ** 2).sum() / (b ** 2).sum()))
    worst = float((np.abs(m - b).max(axis=1) / np.maximum(b.max(axis=1), 1e-3 * b.max())).max())
    print(f"{label}: relative RMS difference {rel:.2e}, worst face {worst:.2e}, {rep['elements']} elements")
    # The issue asks for 1e-3 on the whole bake. Size ties in the refiner and the cluster tree are decided
    # with a relative tolerance, so no refinement decision flips with the rounding of the scaled
    # coordinates: measured 4e-8 RMS and 2.5e-7 on the worst face (1.01e-3 and 6 % before), guarded here
    # a hundred times above that.
    assert rel <= 1e-5
    assert worst <= 1e-4


def closed_box(name, lo, hi, material, inward=True, divisions=(2, 2, 2)):
    mb = scenes.MeshBuilder()
    mb.box(lo, hi, divisions=divisions)
    if inward:
        mb.faces = [tuple(reversed(f)) for f in mb.faces]
    return mb.build(name, [material])


def glowing_white(albedo, strength):
    mat = bpy.data.materials.new("GlowWhite")
    mat.use_nodes = True
    p = mat.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (albedo, albedo, albedo, 1.0)
    compat.principled(p, "Emission").default_value = (1.0, 1.0, 1.0, 1.0)
    p.inputs["Emission Strength"].default_value = strength
    compat.principled(p, "Specular").default_value = 0.0
    p.inputs["Roughness"].default_value = 0.0
    return mat


def test_albedo_099_closed_box_converges(empty_scene, penumbra):
    """Every wall emits L_e and reflects rho: in a closed box the exact answer is uniform, B = B_e / (1 - rho),
    so the stored reflected radiance is rho * L_e / (1 - rho). Each bounce keeps 99 %, so the iteration needs
    hundreds of sweeps, and any loss of energy in the form factors is amplified a hundredfold."""
    rho, strength = 0.99, 0.01
    closed_box("Box", (-1, -1, 0), (1, 1, 2), glowing_white(rho, strength))
    # Uniform radiosity makes every transfer exact whatever the refinement (as in native/python/test_corpus.py's
    # furnace), so a coarse epsilon tests the same thing: 1606 iterations either way, corners 0.99999 x exact
    # (1.00000 at the default epsilon, which took 5 times the CPU). Furnace.HighAlbedoTessellatedTwoThreads
    # (ctest) keeps a furnace at the default epsilon.
    rep = penumbra.bake(empty_scene, resolution=32, tolerance=1e-7, max_iterations=20000, epsilon=0.01,
                        min_size=0.05)
    solver = rep["solver"]
    expected = rho * strength / (1 - rho)
    img = bpy.data.images[rep["outputs"]["Box"]["image"]]
    px = image_pixels(img)[..., :3]
    ob = bpy.data.objects["Box"]
    ca = ob.data.color_attributes["Penumbra"]
    corners = np.empty(len(ca.data) * 4, np.float32)
    ca.data.foreach_get("color", corners)
    corners = corners.reshape(-1, 4)[:, :3]
    print(f"albedo {rho}: {rep['iterations']} iterations, residual {rep['residual']:.2e}, converged "
          f"{solver.get('converged')}; corners mean {corners.mean() / expected:.5f} x exact, range "
          f"{corners.min() / expected:.5f}..{corners.max() / expected:.5f}; texels "
          f"{px.min() / expected:.5f}..{px.max() / expected:.5f}")
    assert solver.get("converged") is True
    assert rep["iterations"] < 20000
    assert np.isfinite(px).all() and np.isfinite(corners).all()
    assert abs(corners.mean() / expected - 1) < 0.01
    assert np.abs(corners / expected - 1).max() < 0.03


def sliver_fan(name, apex, length, spread_deg, count, z, material):
    """Triangles of width length*spread/count: aspect ratios in the thousands."""
    verts = [apex]
    for k in range(count + 1):
        a = math.radians(spread_deg) * k / count
        verts.append((apex[0] + length * math.cos(a), apex[1] + length * math.sin(a), z))
    faces = [(0, k, k + 1) for k in range(1, count + 1)]
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.materials.append(material)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def corner_colors(ob):
    ca = ob.data.color_attributes["Penumbra"]
    a = np.empty(len(ca.data) * 4, np.float32)
    ca.data.foreach_get("color", a)
    return a.reshape(-1, 4)[:, :3]


def test_slivers_contact_and_sealed_box(empty_scene, penumbra):
    """A lit Cornell box with sliver triangles on its floor, a cube resting on the floor, and a sealed box
    right behind its back wall: no NaN, no negative value, and no light where none can arrive."""
    obs = cornell_box.build()
    grey = scenes._diffuse("Grey", (0.6, 0.6, 0.6))
    sliver_fan("Slivers", (0.2, -0.9, 0.0005), 0.6, 0.5, 40, 0.0005, grey)
    resting = closed_box("Resting", (-0.3, -0.8, 0.0), (0.0, -0.5, 0.3), scenes._diffuse("Resting", (0.7,) * 3),
                         inward=False, divisions=(1, 1, 1))
    sealed = closed_box("Sealed", (-0.5, 1.0005, 0.2), (0.5, 1.8, 1.2), scenes._diffuse("Sealed", (0.7,) * 3))
    rep = penumbra.bake(empty_scene, resolution=64)
    print(penumbra.summary(rep), rep["warnings"])
    assert "Slivers" in rep["objects_baked"] and "Sealed" in rep["objects_baked"]
    for name in rep["objects_baked"]:
        img = bpy.data.images[rep["outputs"][name]["image"]]
        px = image_pixels(img)
        c = corner_colors(bpy.data.objects[name])
        assert np.isfinite(px).all() and np.isfinite(c).all(), name
        assert px.min() >= 0 and c.min() >= 0, name
    floor = corner_colors(obs["Floor"]).mean()
    assert floor > 0
    # Only the sealed box's inside exists, and nothing inside it emits.
    assert corner_colors(sealed).max() <= 1e-6 * floor
    # The resting cube's bottom face touches the floor and faces the black outside below it.
    me = resting.data
    bottom = [p for p in me.polygons if p.normal.z < -0.99]
    assert len(bottom) == 1
    loops = list(range(bottom[0].loop_start, bottom[0].loop_start + bottom[0].loop_total))
    assert corner_colors(resting)[loops].max() <= 1e-3 * floor
    # The slivers lie on the lit floor, so they are lit about as the floor is there.
    slivers = corner_colors(bpy.data.objects["Slivers"])
    assert slivers.mean() > 0.2 * floor


def test_faces_flush_under_furniture_stay_dark(empty_scene, penumbra):
    """The office's desk legs end flush under the desk tops. Their top faces see nothing; cluster links, blind to
    shadows inside a cluster, lit them at a third of the desk tops' brightness (0.72 against 2.19 here) until
    faces inside solids were left out of cluster links."""
    from penumbra.compare import face_means, uv_owner
    scenes.build("office")
    rep = penumbra.bake(empty_scene, resolution=128, targets={"LIGHTMAP"})   # leg tops get texels from 128
    assert rep["clusters"] > 1 and rep["cluster_links"] > 0
    ob = bpy.data.objects["Furniture"]
    me = ob.data
    img = bpy.data.images[rep["outputs"]["Furniture"]["image"]]
    w, h = img.size
    means, count = face_means(image_pixels(img), uv_owner(me, ob["penumbra"]["uv_map"], w, h), len(me.polygons))
    mw = ob.matrix_world
    legs = [p.index for p in me.polygons
            if p.normal.z > 0.99 and p.area < 0.005 and abs((mw @ p.center).z - 0.72) < 1e-3 and count[p.index] > 0]
    tops = [p.index for p in me.polygons if p.normal.z > 0.99 and abs((mw @ p.center).z - 0.76) < 1e-3]
    assert len(legs) >= 4 and tops
    lit = float(np.median(means[tops, :3]))
    worst = float(means[legs, :3].max())
    print(f"desk tops {lit:.3f}, flush leg tops at most {worst:.2e} ({len(legs)} faces)")
    assert lit > 0.1
    assert worst <= 1e-3 * lit
