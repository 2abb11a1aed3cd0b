"""The solver's settings, listed once for the add-on: name, type, default, accepted range, label, help and
where the panel shows them. Plain data, importable without bpy or the native module (cli.py reads it before
Blender's data is loaded).

Built from this table: the scene properties and the Advanced panel (properties.py, panels.py), the CLI's
flags and their range checks (cli.py), and the keywords penumbra.bake() passes to the solver (__init__.py).

The solver has its own list, PENUMBRA_SETTINGS in native/src/solve/settings.h, from which its Settings struct,
its range checks and the binding's parser are generated; the module exports it as `_native.SETTINGS`.
native/python/test_settings_table.py fails unless every name, type, default and range here equals the
solver's, and blender_tests/test_settings_table.py checks the properties and flags built from this table.

ADDING A SETTING: one X(...) line in native/src/solve/settings.h and one Setting(...) entry below (give it a
group to show it in the panel and the CLI). Nothing else needs editing.
"""
from dataclasses import dataclass, field

INF = float("inf")

# The panel's quality presets set these solver settings (measured on the Cornell box, see docs/ui.md); the
# panel starts at DEFAULT_QUALITY, so those settings' panel defaults are that preset's values, not the
# solver's (min_size: 0.005 in the panel, 0.01 for penumbra.bake() and the solver).
PRESETS = {
    "DRAFT": {"epsilon": 0.002, "min_size": 0.02},
    "MEDIUM": {"epsilon": 0.0005, "min_size": 0.01},
    "HIGH": {"epsilon": 0.0002, "min_size": 0.005},
}
DEFAULT_QUALITY = "HIGH"

# The Advanced panel's columns, in order: (group, heading, the bool setting that switches the group's other
# settings on; it is drawn as the heading's checkbox).
PANEL_GROUPS = (
    ("refinement", "", None),
    ("solve", "", None),
    ("convolution", "Shadow Textures", "convolution"),
)


@dataclass(frozen=True)
class Setting:
    name: str            # the key of the solver's settings dict, of penumbra.bake() and of scene.penumbra
    type: type           # float, int or bool
    default: object      # the solver's default
    # The values the solver accepts, as an interval (lo, min, max, hi): lo "[" or "(", hi "]" or ")"; an open
    # bound refuses the bound itself, INF is no bound ("(", 0.0, INF, ")": finite and above 0). None for bool.
    range: tuple
    label: str
    help: str
    # The Advanced panel's column (a PANEL_GROUPS key). "" keeps the setting out of the add-on: no property, no
    # CLI flag, no penumbra.bake() keyword; only _native.solve() takes it (the budgets).
    group: str = ""
    # Further bpy.props options for the panel (precision, step, subtype, unit). "min" and "max" here narrow the
    # panel's range where the solver's is open or wider than a slider should go; they must lie inside it.
    blender: dict = field(default_factory=dict)
    metavar: str = ""    # the CLI's name for the value; default X for numbers, N for integers

    @property
    def panel(self):
        """Shown in the Advanced panel, a scene property, a CLI flag and a penumbra.bake() keyword."""
        return bool(self.group)

    @property
    def flag(self):
        return "--" + self.name.replace("_", "-")

    def contains(self, x):
        """Whether the solver accepts x (False for NaN), as SettingInfo::contains in settings.h."""
        lo, a, b, hi = self.range
        return (x > a if lo == "(" else x >= a) and (x < b if hi == ")" else x <= b)

    def describe(self):
        """What an error says the value must be; the solver's messages use the same words."""
        lo, a, b, hi = self.range
        integer = self.type is int
        if b == INF:
            if hi == ")" and not integer:
                return f"a finite number {'>' if lo == '(' else '>='} {_number(a, False)}"
            return f"{'greater than' if lo == '(' else 'at least'} {_number(a, integer)}"
        return f"in {lo}{_number(a, integer)}, {_number(b, integer)}{hi}"


def _number(x, integer):
    if x == INF:
        return "inf"
    return str(int(x)) if integer else "%g" % x


SETTINGS = (
    Setting("epsilon", float, 0.0002, ("(", 0.0, INF, ")"), "Refinement Threshold",
            "Subdivide wherever the light transfer's error is above this fraction of the brightest light. "
            "Smaller gives softer, more exact shadows and costs more time and memory",
            group="refinement", blender={"min": 1e-7, "max": 1.0, "precision": 5, "step": 0.01}),
    Setting("min_size", float, 0.01, ("(", 0.0, 1.0, ")"), "Smallest Patch",
            "Surfaces are never cut finer than this fraction of the scene's size (its bounding-box diagonal, "
            "or 35 times its median piece where that is smaller, so a large hall is cut as finely as a room). "
            "Smaller resolves sharper shadow edges and costs more memory",
            group="refinement", blender={"min": 1e-5, "max": 0.5, "precision": 4, "step": 0.01}),
    Setting("visibility_rays", int, 16, ("[", 1, 256, "]"), "Shadow Rays",
            "Rays that test how much of a light or surface another surface sees, where it is partly hidden. "
            "More rays give smoother penumbras", group="refinement"),
    Setting("max_iterations", int, 5000, ("[", 1, 2**31 - 1, "]"), "Max Iterations",
            "Upper limit on the light-bounce iterations. The report warns when the limit stopped the solve "
            "before it converged", group="solve", blender={"max": 100000}),
    Setting("tolerance", float, 1e-4, ("(", 0.0, 1.0, ")"), "Convergence",
            "The bounces stop when the estimated remaining error of the light falls below this fraction",
            group="solve", blender={"min": 1e-9, "max": 0.5, "precision": 6, "step": 0.001}),
    Setting("refine_passes", int, 3, ("[", 1, 20, "]"), "Refine Passes",
            "Times the subdivision is revisited once the bounced light is known: later passes refine where "
            "indirect light matters", group="solve", blender={"max": 16}),
    Setting("threads", int, 0, ("[", 0, 1024, "]"), "Threads",
            "CPU threads for the solver. 0: all cores, except that the Bake button leaves one core to Blender "
            "so that the window stays responsive", group="solve"),
    Setting("clustering", bool, True, None, "Clustering",
            "Group faces into clusters so that distant groups exchange light as one. Much faster on scenes "
            "with many faces; off compares every face with every other face first", group="solve"),
    Setting("convolution", bool, True, None, "Shadow Textures",
            "Let large flat surfaces lit by a flat light through objects take their shadow as one texture "
            "computed by convolution (Soler & Sillion) instead of a mesh cut finely along the penumbra. Used "
            "only where the texture meets the size, error and time limits (Min Receiver Size, Max Blocker "
            "Error, Max Texture Time). Also the soft shadows of suns and point lamps with a size on faces whose "
            "blockers are flat layers clear of them",
            group="convolution"),
    Setting("a_min", float, 0.15, ("[", 0.0, INF, ")"), "Min Receiver Size",
            "Smallest surface (its bounding-box diagonal, as a fraction of the scene's) that may take a shadow "
            "texture. Smaller lets more surfaces take one, at more textures",
            group="convolution", blender={"max": 1.0, "precision": 3, "step": 1}),
    Setting("e_max", float, 1.0, ("(", 0.0, INF, ")"), "Max Blocker Error",
            "How far a shadow texture may misplace a penumbra because its blockers are thick, in units of half "
            "the narrowest penumbra. Larger accepts more textures and less exact shadows",
            group="convolution", blender={"min": 0.01, "max": 100.0, "precision": 2, "step": 10}),
    Setting("t_max", float, 0.05, ("(", 0.0, INF, ")"), "Max Texture Time",
            "Longest predicted time for one shadow texture's FFTs, in seconds; a texture predicted to take "
            "longer is left to the ordinary refinement", group="convolution", metavar="SECONDS",
            blender={"min": 1e-4, "max": 60.0, "precision": 3, "step": 1, "subtype": "TIME_ABSOLUTE",
                     "unit": "TIME_ABSOLUTE"}),
    Setting("max_texture", int, 512, ("[", 16, 4096, "]"), "Max Texture Size",
            "Largest shadow texture, in texels per side", group="convolution"),
    Setting("contact_slabs", bool, False, None, "Contact Shadow Textures",
            "Let an object resting on a surface (a box on the floor, table legs) shadow it through a texture too, "
            "its blocker cut into thin slabs near the contact. Off by default: exact contact shadows on furniture "
            "scenes, but on the Cornell box it measured less accurate than the ordinary refinement",
            group="convolution"),
    Setting("planar_clusters", bool, False, None, "Planar Receivers",
            "Keep faces that lie in one plane together (a floor or wall modelled in one mesh with the rest of the "
            "room, a table top made of triangles), so that the whole plane can take one shadow texture. Off by "
            "default: it changes how the ordinary refinement groups faces", group="convolution"),
    Setting("wall_links", bool, False, None, "Wall Shadow Textures",
            "Let a surface steep to a lamp (a wall under a ceiling lamp) take shadow textures too, cut into "
            "horizontal bands below the lamp. Off by default: textures are made only where the blockers are flat "
            "along the lamp's axis (shelves, table tops); furniture with tall faces is left to the ordinary "
            "refinement", group="convolution"),
    Setting("cluster_receivers", bool, True, None, "Grouped Receivers",
            "Let a group of faces that do not lie in one plane (a vault, a terrain, a curved cushion) take one "
            "shadow texture for the whole group, each face lit at its own position and angle. A group whose "
            "faces shade one another from the lamp is left to the ordinary refinement, as is everything when "
            "this is off", group="convolution"),
    Setting("indirect_sources", bool, False, None, "Bounced Light Shadow Textures",
            "Let a brightly lit surface (a ceiling over an uplight, a sunlit wall) cast its bounced light through "
            "blockers as shadow textures too, weighted by its own light and shadows. Off by default: not yet "
            "compared with Cycles on furnished rooms", group="convolution"),
    Setting("far_field", float, 0.3, ("(", 0.0, 1.0, "]"), "Cluster Far Field",
            "A group of objects sends its bounced light over one link once it is farther than its own radius "
            "divided by this. Larger makes fewer links, uses less memory and is faster (0.3 against 0.2: 29 "
            "percent less time on a 10,000-polygon office), but from about 0.35 it is less exact close to groups "
            "of objects (the inside of an open box)",
            group="refinement", blender={"min": 0.05, "max": 1.0, "precision": 2, "step": 5}),
    Setting("source_shares", bool, True, None, "Shared Near Groups",
            "Let a nearby group of objects whose bounced light on a patch or a small group is small send it over "
            "one link, each face with its own share of visibility, instead of one link per face: a quarter to a "
            "third less time and about half the links on a large furnished room, as exact against Cycles",
            group="refinement"),
    Setting("contact_floor", float, 0.0, ("[", 0.0, INF, ")"), "Contact Floor",
            "0: the smallest patch is Min Size everywhere. More: a face that a smaller object touches or nearly "
            "touches (a stand on a desk, a chair leg on the floor) may be cut down to this many times that "
            "object's face size there, so the light around small things is as detailed as they are. 1 is about "
            "twice the time on a furnished office for a fifth less error against Cycles; 2 is about a third more "
            "time for an eighth less", group="refinement", blender={"min": 0.0, "max": 8.0, "precision": 2, "step": 25}),
    Setting("final_gather", bool, True, None, "Final Gather",
            "Evaluate the light coming straight from the lamps exactly at every texel and vertex (exact form "
            "factors, visibility from the solution) instead of reading it from the patches: no patch blotches "
            "and exact hot spots near lamps. The patches then carry only the bounced light",
            group="refinement"),
    Setting("gather_rays", int, 0, ("[", 0, 256, "]"), "Gather Rays",
            "0: the final gather's shadows come from the solution (smooth, as exact as the refinement). More: "
            "up to this many shadow rays per lamp and texel instead (sharper contact shadows, but detailed "
            "shadows need hundreds)", group="refinement"),
    Setting("light_rays", int, 256, ("[", 1, 1024, "]"), "Light Rays",
            "Shadow rays per point, spot or sun lamp with a size (radius, angle) and for the world, per texel: "
            "the steps of their soft shadows (a lamp of radius 0 takes one ray, a hard shadow)",
            group="refinement"),
    Setting("texel_samples", int, 1, ("[", 1, 16, "]"), "Texel Samples",
            "1: every lightmap texel takes the light at its centre. More: texels on a shadow's edge or a contact "
            "take the mean over their area from this many points per side, as Cycles' bake does, so shadows "
            "narrower than a texel come out as their share of it. Worth it with point, spot and sun lamps or "
            "Gather Rays; with the default shadows, read from the patches, it changes little", group="refinement"),
    Setting("seed", int, 0, ("[", 0, 2**31 - 1, "]"), "Seed",
            "Which sample pattern the rays use. Another seed gives a bake that differs only by sampling noise: "
            "bake two to see how much of a difference is noise", group="refinement"),
    # Budgets: the solver stops with BudgetExceeded before taking the memory. Not in the panel.
    Setting("max_elements", int, 2000000, ("[", 1, 2**30, "]"), "Max Elements",
            "Quadtree elements, about 400 bytes each at the peak"),
    Setting("max_links", int, 60000000, ("[", 1, INF, "]"), "Max Links",
            "Links, about 72 bytes each at the peak (the 100k-polygon office at the default epsilon: 34M in 2.1 GB)"),
    Setting("max_face_pairs", float, 1e9, ("[", 1.0, INF, "]"), "Max Face Pairs",
            "Receiving x sending faces visited at the top level with clustering off"),
    Setting("max_texels", int, 8192 * 8192, ("[", 1, INF, "]"), "Max Texels",
            "Texels of one lightmap, about 60 bytes each while baking"),
)

BY_NAME = {s.name: s for s in SETTINGS}
# What penumbra.bake() passes to the solver, the panel's Advanced settings and the CLI's solver flags.
PANEL = tuple(s for s in SETTINGS if s.panel)
SOLVER_KEYS = tuple(s.name for s in PANEL)


def panel_default(s):
    """The property's default: the default quality preset's value where it sets this setting."""
    return PRESETS[DEFAULT_QUALITY].get(s.name, s.default)


def panel_limits(s):
    """(min, max) of the panel's property: the "min"/"max" of s.blender, else the solver's closed bounds."""
    lo, a, b, hi = s.range
    return (s.blender.get("min", a), s.blender.get("max", b))
