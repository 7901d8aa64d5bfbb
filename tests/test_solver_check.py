"""Without PyNumero's ASL library a solve stops first with how to fix it (not Pyomo's
opaque AttributeError), and the run folder records the diagnosis."""
import json


from ocdsl.api import run_file


def test_missing_asl_library_is_explained(configs, tmp_path, monkeypatch):
    from pyomo.contrib.pynumero.asl import AmplInterface

    monkeypatch.setattr(AmplInterface, "available", classmethod(lambda cls: False))
    out = tmp_path / "run"
    res = run_file(configs / "double_integrator.yaml", out)
    assert res.status == "error"
    assert "libpynumero_ASL" in res.message and "make setup" in res.message
    saved = json.loads((out / "result.json").read_text())
    assert saved["status"] == "error" and "make setup" in saved["message"]
    assert not res.ok
