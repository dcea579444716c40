"""A mypy plugin for Warp's kernel language: its value types support the operators mypy cannot see.

Warp's stubs (warp/__init__.pyi) declare the kernel value types (`vec3d`, `quatd`, `mat33d`, the
generic `Vector`, `Quaternion`, `Matrix`, `Transformation`) with their constructors only: the
arithmetic, indexing and component access that kernels use on them (`p_b - p_a`, `h[0]`, `q * v`)
are compiled by Warp and declared nowhere, and a `vec3d` is not even a `Vector[float64, 3]` to the
checker, so every kernel line would read as an error. This plugin gives those classes an Any
fallback, as if they derived from Any: their constructors are still checked, everything else they
do is Any; `wp.types.vector(length, dtype)` makes such a class too, and so does Tumble's
`structs.array_struct` (a Warp struct whose fields a field table names). `wp.tid()` returns one
index or a tuple depending on how the caller unpacks it, which a return type cannot say; its
calls are typed Any.

Host code keeps Warp's own types (`wp.array`, `wp.launch`, `wp.zeros`, ...). The annotations of
kernel arguments (`wp.array(dtype=vec3)`) are calls, which no plugin can turn into types: the
kernel modules disable `valid-type` for that (pyproject.toml, [tool.mypy]).
"""

from __future__ import annotations

import re
from collections.abc import Callable

from mypy.nodes import GDEF, Block, ClassDef, SymbolTable, SymbolTableNode, TypeInfo
from mypy.plugin import ClassDefContext, DynamicClassDefContext, FunctionContext, Plugin
from mypy.types import AnyType, Type, TypeOfAny

# Warp's value types: vectors, matrices, quaternions, transforms, spatial types, and the generic hints
_VALUE_TYPE = re.compile(
    r"warp(\._src\.types)?\.(vec\d\w*|mat\d\d\w*|quat\w*|transform\w*|spatial_\w+"
    r"|Vector|Matrix|Quaternion|Transformation|MeshQuery\w*)"
)
# Warp's scalar types (float64, int32, ...): kernels compare and combine them with each other
_SCALAR_TYPE = re.compile(r"warp(\._src\.types)?\.(u?int(8|16|32|64)|float(16|32|64)|bfloat16)")


def _any_fallback(ctx: ClassDefContext) -> None:
    ctx.cls.info.fallback_to_any = True


def _vector_class(ctx: DynamicClassDefContext) -> None:
    # `vec8 = wp.types.vector(length=8, dtype=float_t)` makes a class, usable in annotations
    defn = ClassDef(ctx.name, Block([]))
    defn.fullname = ctx.api.qualified_name(ctx.name)
    info = TypeInfo(SymbolTable(), defn, ctx.api.cur_mod_id)
    defn.info = info
    base = ctx.api.named_type("builtins.object")
    info.bases = [base]
    info.mro = [info, base.type]
    info.fallback_to_any = True
    ctx.api.add_symbol_table_node(ctx.name, SymbolTableNode(GDEF, info))


def _any_result(ctx: FunctionContext) -> Type:
    return AnyType(TypeOfAny.special_form)


class WarpPlugin(Plugin):
    def get_customize_class_mro_hook(self, fullname: str) -> Callable[[ClassDefContext], None] | None:
        if _VALUE_TYPE.fullmatch(fullname) or _SCALAR_TYPE.fullmatch(fullname):
            return _any_fallback
        return None

    def get_dynamic_class_hook(self, fullname: str) -> Callable[[DynamicClassDefContext], None] | None:
        if fullname in ("warp.types.vector", "warp._src.types.vector", "warp.types.matrix", "warp._src.types.matrix"):
            return _vector_class
        if fullname == "tumble.structs.array_struct":  # a Warp struct whose fields come from a field table
            return _vector_class
        return None

    def get_function_hook(self, fullname: str) -> Callable[[FunctionContext], Type] | None:
        if fullname in ("warp.tid", "warp._src.builtins.tid"):
            return _any_result
        return None


def plugin(version: str) -> type[Plugin]:
    return WarpPlugin
