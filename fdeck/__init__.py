"""fdeck: explicit finite-element forming of dry textile reinforcements.

Stages run in one direction: ``deck`` (YAML -> validated Deck) -> ``compile`` (Deck -> Problem of plain arrays)
-> ``engine`` (numba time loop) -> ``io`` (VTU/PVD, XDMF/HDF5, history, summary).
"""

__version__ = "0.1.0"
