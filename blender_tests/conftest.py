import os
import sys

import bpy
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "examples"))


@pytest.fixture
def empty_scene():
    """A fresh empty file. read_factory_settings would unregister the add-on; read_homefile keeps it."""
    bpy.ops.wm.read_homefile(use_empty=True)
    return bpy.context.scene


@pytest.fixture(scope="module")
def penumbra():
    import penumbra
    return penumbra
