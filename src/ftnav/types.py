"""Array aliases of the public signatures, the shape in the name (spec §0 array convention).

Each alias is a plain :data:`numpy.typing.NDArray` alias: nothing is checked or
converted at run time, the shape lives in the alias's name and in its line below
(in the spirit of dynamax's shape-typed signatures).  Letters of the shapes:

``B``
    the batch: zero or more leading axes that broadcast (Monte Carlo runs, or runs x
    local filters), written ``...`` in the docstrings of :mod:`ftnav.core`; the flat
    kernels of :mod:`ftnav.core.linalg` take exactly one.
``n``, ``m``
    state and measurement dimensions (``N`` local filters, where it matters).

Every float array is float64, the dtype the compiled kernels read.  A parameter typed
:data:`ArrayLike` is converted with ``numpy.asarray`` (a Python float, a list or an
array of any shape that broadcasts, as the docstring says).
"""

from __future__ import annotations

from typing import TypeAlias, TypeVar

import numpy as np
import numpy.typing as npt

__all__ = [
    "Array",
    "ArrayLike",
    "Vector",
    "Matrix",
    "BatchScalar",
    "BatchVector",
    "BatchMatrix",
    "BoolBatch",
    "FloatOrArray",
]

#: float64 array of any shape
Array: TypeAlias = npt.NDArray[np.float64]
#: anything ``numpy.asarray`` turns into an array (a float, a sequence, an array)
ArrayLike: TypeAlias = npt.ArrayLike
#: (n,) one vector, no batch axis
Vector: TypeAlias = Array
#: (m, n) one matrix, no batch axis (square (n, n) for a covariance)
Matrix: TypeAlias = Array
#: (B,) one scalar per batch element, e.g. the NIS
BatchScalar: TypeAlias = Array
#: (B, n) one vector per batch element, e.g. a state mean
BatchVector: TypeAlias = Array
#: (B, m, n) one matrix per batch element, e.g. a covariance (B, n, n)
BatchMatrix: TypeAlias = Array
#: (B,) one flag per batch element, e.g. "the Cholesky factorization succeeded"
BoolBatch: TypeAlias = npt.NDArray[np.bool_]
#: a float in, a float out; an array in, an array out (element-wise functions such as the
#: unit converters of :mod:`ftnav.nav.units`)
FloatOrArray = TypeVar("FloatOrArray", float, Array)
