"""drake_symplan_models: the UR10 + gripper, table and box models (URDF/SDF, package.xml).

Shipped as package data so that an editable install, `pip install .` and a wheel all find
them; `drake_symplan.world.station.models_dir()` locates them with importlib.resources.
"""
