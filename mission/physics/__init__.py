"""Radio physics: propagation models built from named effects, antenna patterns and body-frame
geometry.

>>> from mission.physics import make_model
>>> model = make_model("e2r", pattern="dipole")
>>> rss = model.rss_dbm(tx_enu, rx_enu, attitude_rad)   # tx (..., 3) x rx (N, 3) -> (..., N)
"""

from mission.physics.antenna import (
    Dipole,
    Isotropic,
    Mounted,
    Pattern,
    TabulatedPattern,
    load_aerpaw_pattern,
    load_pattern,
    load_pattern_csv,
    mount_angles,
    rm_wb1_dn,
    save_pattern_csv,
)
from mission.physics.geometry import body_angles, body_from_enu_matrix, enu_to_ned, rotation_nb
from mission.physics.propagation import (
    MODEL_NAMES,
    Attitude,
    FreeSpace,
    GroundReflection,
    LegShadowing,
    Link,
    PathGainSlope,
    PropagationModel,
    RxAntenna,
    TxAntenna,
    make_model,
)

__all__ = [
    "MODEL_NAMES",
    "Attitude",
    "Dipole",
    "FreeSpace",
    "GroundReflection",
    "Isotropic",
    "LegShadowing",
    "Link",
    "Mounted",
    "PathGainSlope",
    "Pattern",
    "PropagationModel",
    "RxAntenna",
    "TabulatedPattern",
    "TxAntenna",
    "body_angles",
    "body_from_enu_matrix",
    "enu_to_ned",
    "load_aerpaw_pattern",
    "load_pattern",
    "load_pattern_csv",
    "make_model",
    "mount_angles",
    "rm_wb1_dn",
    "rotation_nb",
    "save_pattern_csv",
]
