"""Every ```python snippet of docs/python.md runs, in order, in one namespace."""

import re
import warnings

from conftest import ROOT


def test_the_python_walk_through_runs(in_root, capsys):
    text = (ROOT / "docs" / "python.md").read_text()
    snippets = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(snippets) >= 8
    namespace = {"__name__": "docs_python"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, code in enumerate(snippets):
            exec(compile(code, f"docs/python.md snippet {i + 1}", "exec"), namespace)
    # What the walk-through shows.
    assert namespace["report"].converged
    assert namespace["scores"].rms_mm < 3.0
    assert namespace["commands"].unconverged == []
    assert namespace["np"].abs(namespace["check"].positions - namespace["targets"]).max() < 1e-6
    error = namespace["error"]
    assert error.file.endswith("bad.csv") and error.line == 2 and error.field is not None
    assert namespace["best"].nq == namespace["robot"].nq
    assert (namespace["folder"] / "talos_calibrated.urdf").exists()


def test_the_version_is_the_workspace_one():
    import armcomp

    cargo = (ROOT / "Cargo.toml").read_text()
    version = re.search(r'\[workspace\.package\]\nversion = "([^"]+)"', cargo).group(1)
    assert armcomp.__version__ == version
