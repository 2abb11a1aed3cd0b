import os
import sys

# The module is staged by the build next to the add-on's Python files; import it standalone.
_stage = os.environ.get("PENUMBRA_ADDON_DIR",
                        os.path.join(os.path.dirname(__file__), "..", "..", "build", "addon"))
sys.path.insert(0, os.path.join(os.path.abspath(_stage), "penumbra"))
