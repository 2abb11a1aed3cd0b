"""The panel's properties, penumbra.bake()'s keywords and the Advanced panel come from settings_table.py, whose
names, defaults and ranges native/python/test_settings_table.py holds equal to the solver's."""
import bpy
import pytest


@pytest.fixture
def table():
    from penumbra import settings_table
    return settings_table


def _rna():
    return type(bpy.context.scene.penumbra).bl_rna.properties


def test_every_panel_setting_is_a_property_with_the_tables_label_help_default_and_limits(empty_scene, table):
    props = _rna()
    kinds = {float: "FLOAT", int: "INT", bool: "BOOLEAN"}
    for s in table.SETTINGS:
        if not s.panel:
            assert s.name not in props, f"{s.name} is solver-only (no group) but has a property"
            continue
        p = props[s.name]
        assert p.type == kinds[s.type], s.name
        assert (p.name, p.description) == (s.label, s.help), s.name
        if s.type is float:
            assert p.default == pytest.approx(table.panel_default(s), rel=1e-6), s.name
        else:
            assert p.default == table.panel_default(s), s.name
        if s.type is not bool:
            lo, hi = table.panel_limits(s)
            assert (p.hard_min, p.hard_max) == pytest.approx((lo, hi), rel=1e-6), s.name
            assert s.contains(p.hard_min) and s.contains(p.hard_max), s.name     # in the solver's range
        # A fresh scene holds the defaults; the preset's thresholds are the default quality's.
        assert getattr(empty_scene.penumbra, s.name) == pytest.approx(table.panel_default(s), rel=1e-6)


def test_as_settings_and_bake_take_the_panel_settings(empty_scene, penumbra, table):
    s = empty_scene.penumbra.as_settings()
    assert set(table.SOLVER_KEYS) <= set(s)
    assert penumbra.SOLVER_KEYS == table.SOLVER_KEYS
    with pytest.raises(TypeError, match="unknown Penumbra setting"):
        penumbra.bake(empty_scene, max_elements=10)          # solver-only: not a bake() keyword


def test_a_preset_sets_exactly_its_settings(empty_scene, table):
    s = empty_scene.penumbra
    for name, values in table.PRESETS.items():
        s.quality = name
        for key, value in values.items():
            assert getattr(s, key) == pytest.approx(value)
    key = next(iter(table.PRESETS["DRAFT"]))
    setattr(s, key, getattr(s, key) * 1.5)
    assert s.quality == "CUSTOM"


def test_the_advanced_panel_draws_every_panel_setting_once(empty_scene, table):
    """Draw the Advanced panel's body into a recording layout and compare the properties it shows."""
    from penumbra import panels
    shown = []

    class Layout:
        use_property_split = use_property_decorate = active = False

        def column(self, **kw):
            return self

        def prop(self, data, name, **kw):
            shown.append(name)

    class Ctx:
        scene = empty_scene

    fake = type("Fake", (panels._Advanced,), {})()
    fake.layout = Layout()
    fake.draw(Ctx())
    assert sorted(shown) == sorted(s.name for s in table.PANEL)
