"""A four-lane float64 value for the compiled kernels: accumulators that stay in registers.

Numba's loop vectoriser vectorises innermost loops only; a product ``G @ P`` of a few rows by a
small matrix, summed over ``e`` in order (no reassociation, so that the bits are those of the
plain loop), then keeps its partial sums in memory and stores and reloads them for every ``e``.
With :data:`vec4` (an LLVM ``<4 x double>``) a block of columns is accumulated in registers, one
multiply and one add per lane and step, exactly the operations of the scalar loop ``s += g * x``
(no fused multiply-add: LLVM does not contract without fast-math flags), so every lane's result is
bit-identical to it.

Used by :func:`avbench.estimators.online._kernels.nekf_run` (``_gp_rows``); tested there against the
plain loop and the NumPy reference.

Numba's on-disk cache of a kernel is keyed on its own source file only: after editing this module,
touch ``_kernels.py`` (or clear its ``__pycache__``), or a second process loads the kernels compiled
from the previous intrinsics.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

__all__ = ["vec4", "v4_zero", "v4_axpy", "v4_store"]

_V4 = ir.VectorType(ir.DoubleType(), 4)
_I32 = ir.IntType(32)


class Vec4Type(types.Type):
    """Four float64 lanes held in one LLVM vector value."""

    def __init__(self):
        super().__init__(name="Vec4")


vec4 = Vec4Type()


@register_model(Vec4Type)
class _Vec4Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _V4)


def _lanes_pointer(context, builder, aty, arr, i, j):
    """Pointer to ``arr[i, j:j+4]`` (a C-contiguous 2-D float64 array; no wraparound, no bounds check)."""
    ary = context.make_array(aty)(context, builder, arr)
    ptr = cgutils.get_item_pointer(context, builder, aty, ary, [i, j], wraparound=False)
    return builder.bitcast(ptr, _V4.as_pointer())


def _check_matrix(aty):
    if not (isinstance(aty, types.Array) and aty.ndim == 2 and aty.layout == "C" and aty.dtype == types.float64):
        raise TypeError(f"expected a C-contiguous 2-D float64 array, got {aty}")


@intrinsic
def v4_zero(typingctx):
    """Four zeros (+0.0)."""

    def codegen(context, builder, sig, args):
        return ir.Constant(_V4, [0.0] * 4)

    return vec4(), codegen


@intrinsic
def v4_axpy(typingctx, acc, g, arr, i, j):
    """``acc + g * arr[i, j:j+4]`` lane by lane: a multiply, then an add (no fused multiply-add)."""
    _check_matrix(arr)

    def codegen(context, builder, sig, args):
        accv, gv, arrv, iv, jv = args
        x = builder.load(_lanes_pointer(context, builder, sig.args[2], arrv, iv, jv), align=8)
        gs = builder.insert_element(ir.Constant(_V4, ir.Undefined), gv, ir.Constant(_I32, 0))
        gs = builder.shuffle_vector(gs, ir.Constant(_V4, ir.Undefined), ir.Constant(ir.VectorType(_I32, 4), [0] * 4))
        return builder.fadd(accv, builder.fmul(gs, x))

    return vec4(acc, types.float64, arr, types.intp, types.intp), codegen


@intrinsic
def v4_store(typingctx, arr, i, j, v):
    """``arr[i, j:j+4] = v``."""
    _check_matrix(arr)

    def codegen(context, builder, sig, args):
        arrv, iv, jv, vv = args
        builder.store(vv, _lanes_pointer(context, builder, sig.args[0], arrv, iv, jv), align=8)
        return context.get_dummy_value()

    return types.none(arr, types.intp, types.intp, vec4), codegen
