"""`tsim schema` (issue 15): the config's JSON Schema accepts every config in configs/ and
tests/, rejects what tsim rejects as a wrong key or type, and the copy editors point at,
docs/tsim.schema.json, is the one the binary writes. YAML is read by ruamel.yaml, a YAML
1.2 reader like tsim's (PyYAML's 1.1 reads `1e-3` as a string)."""

import io
import json
import subprocess
from pathlib import Path

import jsonschema
import pytest
from ruamel.yaml import YAML

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = sorted(
    p for d in ("configs", "tests") for p in (ROOT / d).rglob("*.yaml")
)


@pytest.fixture(scope="module")
def schema(tsim_bin):
    text = subprocess.run([tsim_bin, "schema"], check=True, capture_output=True, text=True).stdout
    return json.loads(text)


def read_yaml(text):
    return YAML(typ="safe").load(io.StringIO(text))


def test_the_published_copy_is_current(tsim_bin):
    written = subprocess.run([tsim_bin, "schema"], check=True, capture_output=True, text=True).stdout
    assert (ROOT / "docs/tsim.schema.json").read_text() == written, (
        "docs/tsim.schema.json is stale: run `tsim schema --out docs/tsim.schema.json`"
    )


def test_it_is_a_valid_schema(schema):
    jsonschema.Draft202012Validator.check_schema(schema)


def test_configs_are_found():
    # The glob must see the main job and the examples, or the next test checks nothing.
    names = {p.relative_to(ROOT).as_posix() for p in CONFIGS}
    assert {"configs/sweep.yaml", "configs/paper.yaml", "tests/fixtures/small_sweep.yaml"} <= names
    assert sum(n.startswith("configs/examples/") for n in names) >= 5


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_config_validates(schema, path):
    errors = list(jsonschema.Draft202012Validator(schema).iter_errors(read_yaml(path.read_text())))
    assert not errors, "\n".join(f"{'.'.join(map(str, e.absolute_path))}: {e.message}" for e in errors)


# Wrong keys and types in the paper's config, each one tsim refuses as it parses: the
# schema must refuse them too (else an editor would let them through).
BREAKAGES = {
    "unknown top-level key": lambda c: c.update(foldng=c.pop("folding")),
    "unknown nested key": lambda c: c["folding"].update(stepz=3),
    "string for a count": lambda c: c["folding"].update(steps="ten"),
    "unknown mass reading": lambda c: c.update(masses="heavy"),
    "list for a number": lambda c: c["deployment"].update(dt=[0.1]),
    "missing required key": lambda c: c["substitution"].pop("strut"),
}


@pytest.mark.parametrize("what", BREAKAGES)
def test_wrong_keys_and_types_are_refused_by_both(schema, tsim_bin, tmp_path, what):
    config = read_yaml((ROOT / "configs/paper.yaml").read_text())
    BREAKAGES[what](config)
    assert list(jsonschema.Draft202012Validator(schema).iter_errors(config)), f"schema accepts: {what}"
    path = tmp_path / "broken.yaml"
    path.write_text(json.dumps(config))  # JSON is YAML
    res = subprocess.run([tsim_bin, "check", path], capture_output=True, text=True)
    assert res.returncode == 2, f"tsim accepts: {what}\n{res.stdout}"


def test_a_wrong_key_in_a_section_is_named(schema):
    # An optional section is `if object then <section> else null`: a validator (and an
    # editor) reports the wrong key itself, not "not valid under any of the given schemas"
    # for the whole section, as `anyOf [section, null]` made it.
    config = read_yaml((ROOT / "configs/paper.yaml").read_text())
    config["folding"]["stepz"] = 3
    errors = list(jsonschema.Draft202012Validator(schema).iter_errors(config))
    assert [list(e.absolute_path) for e in errors] == [["folding"]]
    assert "'stepz' was unexpected" in errors[0].message, errors[0].message
    # An empty section (null) is still accepted, as tsim accepts it.
    config = read_yaml((ROOT / "configs/paper.yaml").read_text())
    config["folding"]["stepz"] = 3
    config["folding"] = None
    assert not list(jsonschema.Draft202012Validator(schema).iter_errors(config))
