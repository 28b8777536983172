"""The public names of ``retarget``: lazy at run time, yet visible to ``dir()`` and to type checkers."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import retarget
from tests.helpers import REPO

INIT = Path(retarget.__file__)


def type_checking_imports() -> dict[str, str]:
    """name -> module of the imports under ``if TYPE_CHECKING:`` in retarget/__init__.py."""
    tree = ast.parse(INIT.read_text())
    block = next(n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING")
    return {a.name: node.module for node in block.body if isinstance(node, ast.ImportFrom) for a in node.names}


def test_dir_lists_every_public_name():
    assert set(retarget.__all__) <= set(dir(retarget))


def test_type_checkers_see_each_lazy_name_from_the_module_that_defines_it():
    assert type_checking_imports() == retarget._LAZY


@pytest.mark.parametrize("name", sorted(retarget._LAZY), ids=str)
def test_each_lazy_name_resolves_to_its_module(name):
    assert getattr(retarget, name) is getattr(importlib.import_module(retarget._LAZY[name]), name)


def test_import_retarget_stays_cheap():
    code = "import sys, retarget; print(sorted(m for m in sys.modules if m.startswith(('retarget', 'numpy'))))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60).stdout
    assert out.strip() == "['retarget', 'retarget.errors']"


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="has no attribute 'load_clip'"):
        _ = retarget.load_clip  # type: ignore[attr-defined]


def test_the_version_is_defined_once():
    pyproject = (REPO / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in pyproject and "\nversion =" not in pyproject
    assert retarget.__version__.count(".") == 2
