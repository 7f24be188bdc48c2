"""lensbake: lens prescriptions in; first-order and Seidel analysis, exact ray traces, wave
optics (wavefront, MTF, PSF), baked lens-ray-transfer-function tables and depth-of-field
renders out.

Conventions (the same as the command line's): lengths in mm, wavelengths in nm, angles in
degrees. The lens frame has z along the optical axis, light travelling +z, origin at the vertex
of surface 1; surfaces are numbered 1..N from the object side. Every refusal raises
LensbakeError (a ValueError) with the message the command line prints.

    import lensbake
    lens = lensbake.load_lens("dgauss-50mm")
    lens.analyze()["first_order"]["efl"]
"""

from ._native import (
    LOOKUP_BLOCKED,
    LOOKUP_OUTSIDE,
    LOOKUP_PASSES,
    OUTCOME_MISSED,
    OUTCOME_OK,
    OUTCOME_TIR,
    OUTCOME_VIGNETTED,
    Lens,
    LensbakeError,
    Table,
    bake,
    load_lens,
    render,
    tradeoff,
)

read_table = Table.read

__all__ = [
    "LOOKUP_BLOCKED",
    "LOOKUP_OUTSIDE",
    "LOOKUP_PASSES",
    "OUTCOME_MISSED",
    "OUTCOME_OK",
    "OUTCOME_TIR",
    "OUTCOME_VIGNETTED",
    "Lens",
    "LensbakeError",
    "Table",
    "bake",
    "load_lens",
    "read_table",
    "render",
    "tradeoff",
]
