"""Plug-ins: every material, element formulation and effect module, imported explicitly (each registers itself)."""

from fdeck.physics.materials import elastic, fabric_hyper, fabric_membrane, neo_hookean  # noqa: F401
from fdeck.physics.elements import hex8, shell4  # noqa: F401
from fdeck.physics.effects import tool  # noqa: F401  (before contact, which reads its kinds)
from fdeck.physics.effects import boundary, bulk_viscosity, contact, damping, fibre_bending, loads  # noqa: F401,E501
from fdeck.physics.measures import element_average, node_displacement, pin_jointed_shear, surface_waviness  # noqa: F401,E501
from fdeck.physics.effects import grip, symmetry  # noqa: F401
from fdeck.physics.measures import draw_in, wrinkles  # noqa: F401
from fdeck.physics.elements import hex8_ans, hex8_ans_fbar  # noqa: F401
from fdeck.physics.effects import selective_mass  # noqa: F401
from fdeck.physics.effects import subcycling  # noqa: F401
from fdeck.physics.effects import deformation_damping  # noqa: F401
