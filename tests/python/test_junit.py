"""`validate --format junit` loads in a standard JUnit consumer (junitparser)."""
from junitparser import JUnitXml, Failure


def test_junit_loads_with_one_case_per_asset_and_check(run, examples, tmp_path):
    out = tmp_path / "report.xml"
    proc = run("validate", examples, "--format", "junit", "-o", out)
    assert proc.returncode in (0, 1), proc.stderr
    xml = JUnitXml.fromfile(str(out))
    suites = list(xml)
    assert len(suites) == 3
    cases = [c for s in suites for c in s]
    assert len(cases) == 3 * 11
    names = {c.name for c in cases}
    assert {"mesh", "uvs", "sharp-creases", "max-displacement", "textures"} <= names
    failures = [c for c in cases if any(isinstance(r, Failure) for r in c.result)]
    assert len(failures) == sum(s.failures for s in suites)
