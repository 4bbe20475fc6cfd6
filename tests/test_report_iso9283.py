"""`robocal calibrate` with an iso9283 section: iso9283.json in the output and its table in the report."""
import json

from lxml import html as lhtml

from robocal.cli.main import main
from test_iso9283_cli import _write_dataset


def test_calibrate_writes_iso9283_figures_into_the_report(tmp_path):
    config, _ = _write_dataset(tmp_path)
    out = tmp_path / "out"
    assert main(["calibrate", str(config), "-o", str(out), "-q"]) == 0
    iso = json.loads((out / "iso9283.json").read_text())
    nominal = {p["pose"]: p for p in iso["nominal"]["poses"]}
    calibrated = {p["pose"]: p for p in iso["calibrated"]["poses"]}
    assert sorted(nominal) == ["P1", "P2", "P3"]
    # the synthetic robot is millimetres off its model; calibration brings accuracy to tens of microns,
    # while repeatability is the robot's own and stays as measured
    for pid in nominal:
        assert nominal[pid]["AP"] > 1e-3 > 10 * calibrated[pid]["AP"]
        assert abs(nominal[pid]["RP"] - calibrated[pid]["RP"]) < 1e-9
    page = lhtml.fromstring((out / "report.html").read_bytes())
    rows = page.xpath('//table[@class="iso9283"]//tr')
    assert len(rows) == 1 + 2 * 3          # header + (nominal, calibrated) x 3 poses
    assert "ISO 9283" in page.text_content()
