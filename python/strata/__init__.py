"""Strata: layered animation with displacement maps.

    import strata
    strata.bake("scan.ply", "cage.obj", "hero.glb")              # -> the bake report, a dict
    vertices, triangles = strata.load_rig("hero.glb").reconstruct(level=3)

bake() takes strata-bake's options as keywords (help(strata.bake) lists them);
Rig.reconstruct() returns numpy arrays.  Failures raise strata.Error with the
tools' one-line message.  The work runs in C++ with the GIL released.
"""
from ._strata import Error, Rig, __version__, bake, bake_options, load_rig

__all__ = ["Error", "Rig", "bake", "bake_options", "load_rig", "__version__"]
