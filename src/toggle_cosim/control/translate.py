"""Translate the control laws from their Python definition into C: one definition, two forms.

The translator accepts a small subset of Python, enough for pure scalar laws:

* module-level functions whose arguments are floats and at most one frozen parameter
  dataclass (read as ``p.field``), returning a float or a tuple of floats;
* statements: local assignments (a name, or a tuple of names from a tuple-returning call),
  if/elif/else, return, ``raise ValueError(...)``; docstrings are skipped;
* expressions: float constants, + - * /, unary -, comparisons (also chained), and/or/not,
  conditional expressions, ``abs``, and ``math.sin cos asin atan2 sqrt log exp``.

Every function becomes ``static int f(args..., const law_t *p, double *out0, ...)`` returning 0,
or 1 where the Python raises or might raise (a division by zero, a math domain error, an
explicit ``raise``): the caller then hands the sample back to the Python, which decides.
Each Python operation becomes one C operation on doubles, in the order Python evaluates it;
compiled without contraction (``-ffp-contract=off``) and without fast-math, the C gives the
same bits as the Python wherever it returns 0.

The struct ``law_t`` is generated from the dataclass's fields, and so is its ctypes mirror
(`ctypes_struct`): nothing is kept in line by hand.
"""

from __future__ import annotations

import ast
import ctypes
import dataclasses
import inspect
import textwrap
from collections.abc import Callable, Sequence

__all__ = ["TranslationError", "c_struct", "ctypes_struct", "translate_functions"]

_MATH = {"sin": "sin", "cos": "cos", "asin": "asin", "atan2": "atan2", "sqrt": "sqrt", "log": "log", "exp": "exp"}
_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_CMPOPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


class TranslationError(Exception):
    """The Python uses something outside the translator's subset (the message says what, where)."""


def c_struct(params: type, name: str = "law_t") -> str:
    """The C struct of a frozen dataclass of floats, field for field."""
    fields = [f.name for f in dataclasses.fields(params)]
    return "typedef struct {\n" + "".join(f"    double {f};\n" for f in fields) + f"}} {name};\n"


def ctypes_struct(params: type) -> type[ctypes.Structure]:
    """The ctypes mirror of `c_struct(params)`."""
    return type(
        f"{params.__name__}_c",
        (ctypes.Structure,),
        {"_fields_": [(f.name, ctypes.c_double) for f in dataclasses.fields(params)]},
    )


def _returns(fn: ast.FunctionDef) -> int:
    """How many floats the function returns (1 for ``-> float``, n for ``-> tuple[float, ...]``)."""
    ann = fn.returns
    if isinstance(ann, ast.Name) and ann.id == "float":
        return 1
    if isinstance(ann, ast.Subscript) and isinstance(ann.value, ast.Name) and ann.value.id == "tuple":
        elts = ann.slice.elts if isinstance(ann.slice, ast.Tuple) else [ann.slice]
        if all(isinstance(e, ast.Name) and e.id == "float" for e in elts):
            return len(elts)
    raise TranslationError(f"{fn.name}: the return annotation must be float or tuple[float, ...]")


class _Function:
    """The translation of one function."""

    def __init__(self, fn: ast.FunctionDef, arities: dict[str, int], params: type) -> None:
        self.fn, self.arities, self.params = fn, arities, params
        self.param_fields = {f.name for f in dataclasses.fields(params)}
        self.n_out = arities[fn.name]
        self.args: list[str] = []
        self.struct_arg: str | None = None
        for a in fn.args.args:
            ann = a.annotation
            if isinstance(ann, ast.Name) and ann.id == "float":
                self.args.append(a.arg)
            elif isinstance(ann, ast.Name) and ann.id == params.__name__ and self.struct_arg is None:
                self.struct_arg = a.arg
            else:
                raise TranslationError(f"{fn.name}: argument {a.arg} must be a float or one {params.__name__}")
        self.locals: set[str] = set()
        self.temps = 0

    def fail(self, node: ast.AST, what: str) -> TranslationError:
        return TranslationError(f"{self.fn.name}, line {getattr(node, 'lineno', '?')}: {what}")

    def temp(self) -> str:
        self.temps += 1
        name = f"_t{self.temps}"
        self.locals.add(name)
        return name

    # -- expressions: each returns (statements, C expression) ---------------------------------
    def expr(self, node: ast.expr) -> tuple[list[str], str]:
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            return [], repr(float(node.value))
        if isinstance(node, ast.Name):
            if node.id in self.args or node.id in self.locals:
                return [], node.id
            raise self.fail(node, f"unknown name {node.id!r}")
        if isinstance(node, ast.Attribute):
            if isinstance(node.value, ast.Name) and node.value.id == self.struct_arg and node.attr in self.param_fields:
                return [], f"p->{node.attr}"
            raise self.fail(node, f"only {self.struct_arg}.<field> attributes are allowed")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            pre, a = self.expr(node.operand)
            return pre, f"(-{a})"
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            pre, a = self.expr(node.operand)
            return pre, f"(!{a})"
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            pre_a, a = self.expr(node.left)
            pre_b, b = self.expr(node.right)
            out = self.temp()
            guard = [f"if ({b} == 0.0) {{ return 1; }}"] if isinstance(node.op, ast.Div) else []
            return [*pre_a, *pre_b, *guard, f"{out} = {a} {_BINOPS[type(node.op)]} {b};"], out
        if isinstance(node, ast.Compare):
            pre, left = self.expr(node.left)
            parts = []
            for op, right_node in zip(node.ops, node.comparators, strict=True):
                if type(op) not in _CMPOPS:
                    raise self.fail(node, f"comparison {type(op).__name__} is not supported")
                pre_r, right = self.expr(right_node)
                pre += pre_r
                parts.append(f"({left} {_CMPOPS[type(op)]} {right})")
                left = right
            return pre, "(" + " && ".join(parts) + ")"
        if isinstance(node, ast.BoolOp):
            # short-circuit as Python does: later operands are evaluated only when needed
            out = self.temp()
            pre, first = self.expr(node.values[0])
            stmts = [*pre, f"{out} = ({first}) ? 1.0 : 0.0;"]
            for value in node.values[1:]:
                pre_v, v = self.expr(value)
                cond = f"{out} != 0.0" if isinstance(node.op, ast.And) else f"{out} == 0.0"
                stmts.append(f"if ({cond}) {{ " + " ".join([*pre_v, f"{out} = ({v}) ? 1.0 : 0.0;"]) + " }")
            return stmts, out
        if isinstance(node, ast.IfExp):
            out = self.temp()
            pre, test = self.expr(node.test)
            pre_a, a = self.expr(node.body)
            pre_b, b = self.expr(node.orelse)
            return [
                *pre,
                f"if ({test}) {{ "
                + " ".join([*pre_a, f"{out} = {a};"])
                + " } else { "
                + " ".join([*pre_b, f"{out} = {b};"])
                + " }",
            ], out
        if isinstance(node, ast.Call):
            return self.call(node)
        raise self.fail(node, f"{type(node).__name__} is outside the translator's subset")

    def arguments(self, nodes: Sequence[ast.expr]) -> tuple[list[str], list[str]]:
        """Statements and C expressions of call arguments; the parameter struct is passed as p
        (after the floats, as every translated function takes it)."""
        pre: list[str] = []
        args = []
        for a in nodes:
            if isinstance(a, ast.Name) and a.id == self.struct_arg:
                continue
            p, c = self.expr(a)
            pre += p
            args.append(c)
        return pre, args

    def call(self, node: ast.Call) -> tuple[list[str], str]:
        if node.keywords:
            raise self.fail(node, "keyword arguments are not supported")
        pre, args = self.arguments(node.args)
        out = self.temp()
        f = node.func
        if isinstance(f, ast.Name) and f.id == "abs" and len(args) == 1:
            return [*pre, f"{out} = fabs({args[0]});"], out
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "math" and f.attr in _MATH:
            # Python raises (ValueError, OverflowError) where C returns NaN or inf: defer to it
            # for any argument that is not finite or outside the domain, or a result that is not finite
            checks = [f"!isfinite({a})" for a in args]
            if f.attr == "sqrt":
                checks.append(f"{args[0]} < 0.0")
            elif f.attr == "log":
                checks.append(f"{args[0]} <= 0.0")
            elif f.attr == "asin":
                checks.append(f"{args[0]} < -1.0 || {args[0]} > 1.0")
            return [
                *pre,
                f"if ({' || '.join(checks)}) {{ return 1; }}",
                f"{out} = {_MATH[f.attr]}({', '.join(args)});",
                f"if (!isfinite({out})) {{ return 1; }}",
            ], out
        if isinstance(f, ast.Name) and self.arities.get(f.id) == 1:
            return [*pre, f"if ({f.id}({', '.join([*args, 'p', '&' + out])})) {{ return 1; }}"], out
        raise self.fail(node, "only abs, math.<function> and the translated functions of one result may be called here")

    # -- statements ---------------------------------------------------------------------------
    def block(self, body: Sequence[ast.stmt]) -> list[str]:
        lines: list[str] = []
        for stmt in body:
            lines += self.statement(stmt)
        return lines

    def statement(self, node: ast.stmt) -> list[str]:
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            return []  # a docstring
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
            if isinstance(target, ast.Name):
                pre, value = self.expr(node.value)
                self.locals.add(target.id)
                return [*pre, f"{target.id} = {value};"]
            if isinstance(target, ast.Tuple) and all(isinstance(t, ast.Name) for t in target.elts):
                names = [t.id for t in target.elts]
                for name in names:
                    self.locals.add(name)
                value = node.value
                if (
                    isinstance(value, ast.Call)
                    and isinstance(value.func, ast.Name)
                    and self.arities.get(value.func.id) == len(names)
                ):
                    pre, args = self.arguments(value.args)
                    outs = ", ".join(f"&{n}" for n in names)
                    return [*pre, f"if ({value.func.id}({', '.join([*args, 'p', outs])})) {{ return 1; }}"]
                if isinstance(value, ast.Tuple) and len(value.elts) == len(names):
                    pre, temps = [], []
                    for v in value.elts:  # all values first, then the names: Python's order
                        p, c = self.expr(v)
                        t = self.temp()
                        pre += [*p, f"{t} = {c};"]
                        temps.append(t)
                    return [*pre, *(f"{n} = {t};" for n, t in zip(names, temps, strict=True))]
            raise self.fail(node, "only name = expr and names = call/tuple assignments are supported")
        if isinstance(node, ast.If):
            pre, test = self.expr(node.test)
            lines = [*pre, f"if ({test}) {{", *("    " + line for line in self.block(node.body)), "}"]
            if node.orelse:
                lines[-1] = "} else {"
                lines += [*("    " + line for line in self.block(node.orelse)), "}"]
            return lines
        if isinstance(node, ast.Return) and node.value is not None:
            values = node.value.elts if isinstance(node.value, ast.Tuple) else [node.value]
            if len(values) != self.n_out:
                raise self.fail(node, f"returns {len(values)} values, the annotation says {self.n_out}")
            pre, outs = [], []
            for v in values:
                p, c = self.expr(v)
                pre += p
                outs.append(c)
            return [*pre, *(f"*out{i} = {c};" for i, c in enumerate(outs)), "return 0;"]
        if (
            isinstance(node, ast.Raise)
            and isinstance(node.exc, ast.Call)
            and isinstance(node.exc.func, ast.Name)
            and node.exc.func.id == "ValueError"
        ):
            return ["return 1;  /* raise ValueError */"]
        raise self.fail(node, f"{type(node).__name__} is outside the translator's subset")

    def translate(self) -> tuple[str, str]:
        """(prototype, definition)."""
        body = self.block(self.fn.body)
        args = [f"double {a}" for a in self.args] + ["const law_t *p"] + [f"double *out{i}" for i in range(self.n_out)]
        head = f"static int {self.fn.name}({', '.join(args)})"
        declared = sorted(self.locals - set(self.args))
        decl = [f"    double {', '.join(declared)};"] if declared else []
        return head + ";", "\n".join(
            [head + " {", *decl, *("    " + line for line in body), "    return 1;  /* no return reached */", "}"]
        )


def translate_functions(functions: Sequence[Callable], params: type) -> str:
    """C source of the given module-level functions (callees listed before or after callers)."""
    trees = []
    for function in functions:
        tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
        fn = tree.body[0]
        if not isinstance(fn, ast.FunctionDef):
            raise TranslationError(f"{function.__name__}: not a plain function")
        trees.append(fn)
    arities = {fn.name: _returns(fn) for fn in trees}
    parts = [_Function(fn, arities, params).translate() for fn in trees]
    return "\n".join([*(proto for proto, _ in parts), "", *("\n" + body for _, body in parts)]) + "\n"
