"""Tests of scripts/docs_gen.py's audit: a number typed into the docs fails it, an input
listed with its source passes only while the source holds it, and generated text, references
and seed names pass. Run by .ci/run (python3 -m pytest -q scripts/test_docs_gen.py)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import docs_gen  # noqa: E402


def tree(tmp_path, doc, inputs="", source="", module=""):
    (tmp_path / "docs").mkdir()
    (tmp_path / "scripts" / "docsgen").mkdir(parents=True)
    (tmp_path / "docs" / "a.md").write_text(doc)
    (tmp_path / "scripts" / "docsgen" / "inputs.toml").write_text(inputs)
    (tmp_path / "src.rs").write_text(source)
    if module:
        (tmp_path / "scripts" / "docsgen" / "m.py").write_text(module)
    return docs_gen.audit(root=tmp_path, files=[tmp_path / "docs" / "a.md"])


def test_a_typed_result_fails(tmp_path, capsys):
    assert tree(tmp_path, "The fit reaches 3.53e-7 m.\n") == 1
    assert "3.53e-7" in capsys.readouterr().out


def test_generated_text_references_and_seed_names_pass(tmp_path):
    doc = ("Tables 2.3/2.4 and eq. 3.1-3.3; seeds 20261139-50, case 92.\n"
           "It reaches <!-- gen:x -->3.53e-7 m<!-- /gen:x -->.\n"
           "```text\nrmse 0.123\n```\n")
    assert tree(tmp_path, doc) == 0


def test_an_input_passes_while_its_source_holds_it(tmp_path, capsys):
    doc = "A mode at 103 Hz, 15 % of the noise, 40,000 samples, a margin of -10.\n"
    inputs = ('["docs/a.md"]\n"103" = "src.rs: the mode"\n"15 %" = "src.rs: share"\n'
              '"40,000" = "src.rs: samples"\n"-10" = "src.rs: margin"\n')
    assert tree(tmp_path, doc, inputs, "MODE = 103.0; SHARE = 0.15; N = 40_000; M = 10.0") == 0
    capsys.readouterr()
    changed = tmp_path / "changed"
    changed.mkdir()
    assert tree(changed, doc, inputs, "MODE = 104.0; SHARE = 0.15; N = 40_000; M = 10.0") == 1
    assert "103 is not in src.rs" in capsys.readouterr().out


def test_an_entry_no_longer_in_its_file_is_stale(tmp_path, capsys):
    assert tree(tmp_path, "Nothing here.\n", '["docs/a.md"]\n"0.7" = "an old input"\n') == 1
    assert "no longer in that file" in capsys.readouterr().out


def test_a_number_a_render_function_types_fails(tmp_path, capsys):
    module = ('def collect(ctx):\n    return {"args": "--budget 4000"}\n\n\n'
              'def render(d):\n    """Docstring 1.5 ignored."""\n'
              '    return {"x": f"It reaches {d[\'v\']} against the published 3.53e-7 m."}\n')
    assert tree(tmp_path, "Nothing.\n", "", "", module) == 1
    out = capsys.readouterr().out
    assert "3.53e-7" in out and "4000" not in out and "1.5" not in out
