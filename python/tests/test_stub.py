"""The shipped type stub (lmalign/__init__.pyi) names exactly what the package exports."""
import ast
import pathlib

import lmalign


def stub_tree():
    return ast.parse((pathlib.Path(lmalign.__file__).parent / "__init__.pyi").read_text())


def test_stub_lists_every_export_and_nothing_else():
    tree = stub_tree()
    names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    names |= {n.target.id for n in tree.body if isinstance(n, ast.AnnAssign)}
    assert set(lmalign.__all__) <= names
    # Without lmalign::merge (no Ceres at build time) the merge names are absent on purpose.
    absent_on_purpose = set() if lmalign.HAVE_MERGE else set(lmalign.MERGE_NAMES)
    assert {n for n in names if not hasattr(lmalign, n)} == absent_on_purpose
    assert set(lmalign.MERGE_NAMES) <= names


def test_stub_classes_have_the_runtime_attributes():
    tree = stub_tree()
    classes = ["Map", "AlignmentResult"]
    if lmalign.HAVE_MERGE:
        classes += ["MapPrior", "ManifestEntry", "Manifest", "CandidatePair", "Edge", "MapPose",
                    "EdgeReport", "PoseGraphResult", "OverlapCheck"]
    for name in classes:
        node = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == name)
        stub = {f.name for f in node.body if isinstance(f, ast.FunctionDef)}
        runtime = {a for a in dir(getattr(lmalign, name)) if not a.startswith("_")}
        assert runtime == stub - {"__len__", "__init__"}, name
