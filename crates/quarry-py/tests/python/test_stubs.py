"""quarry.pyi describes the module: the same public names, the same parameter names and
defaults for every function and method, and every binding has a docstring."""
import ast
import inspect
import pathlib

import pytest

import quarry

STUBS = ast.parse((pathlib.Path(__file__).resolve().parents[2] / "quarry.pyi").read_text())
HELPERS = {"MotSummary", "Gospa", "IcpResult", "MrclamResult", "KeypointArray", "MatchArray", "F64", "F32", "I64", "I32", "U8"}


def stub_defs():
    out = {}
    for node in STUBS.body:
        if isinstance(node, ast.FunctionDef):
            out[node.name] = node
        elif isinstance(node, ast.ClassDef):
            out[node.name] = node
            for sub in node.body:
                if isinstance(sub, ast.FunctionDef):
                    out[f"{node.name}.{sub.name}"] = sub
    return out


DEFS = stub_defs()
PUBLIC = sorted(n for n in dir(quarry) if not n.startswith("_"))


def test_same_public_names():
    stubbed = {n for n in DEFS if "." not in n} - HELPERS
    assert set(PUBLIC) == stubbed


def runtime_params(obj):
    sig = inspect.signature(obj)
    return [(p.name, None if p.default is inspect.Parameter.empty else p.default)
            for p in sig.parameters.values() if p.name not in ("self", "$self")]


def stub_params(node):
    a = node.args
    names = [x.arg for x in a.args if x.arg != "self"]
    defaults = [None] * (len(names) - len(a.defaults)) + [ast.literal_eval(d) for d in a.defaults]
    return list(zip(names, defaults))


@pytest.mark.parametrize("name", [n for n in PUBLIC if inspect.isbuiltin(getattr(quarry, n))])
def test_function_signatures_match(name):
    f = getattr(quarry, name)
    assert f.__doc__ and len(f.__doc__) > 20
    got = runtime_params(f)
    want = stub_params(DEFS[name])
    assert [g[0] for g in got] == [w[0] for w in want]
    for (n, g), (_, w) in zip(got, want):
        if w is not None and g is not Ellipsis:  # pyo3 shows tuple / Some(..) defaults as ...
            assert g == w, n


@pytest.mark.parametrize("name", [n for n in PUBLIC if inspect.isclass(getattr(quarry, n))])
def test_classes_match(name):
    cls = getattr(quarry, name)
    assert cls.__doc__
    got = runtime_params(cls)
    want = stub_params(DEFS[f"{name}.__init__"])
    assert [g[0] for g in got] == [w[0] for w in want]
    methods = {n for n in dir(cls) if not n.startswith("_")}
    stubbed = {k.split(".", 1)[1] for k in DEFS if k.startswith(name + ".") and not k.endswith("__init__")}
    assert methods == stubbed
