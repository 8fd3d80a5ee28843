"""The example script (python/examples/register_phantom.py) runs and registers."""
import importlib.util
import pathlib


def test_example_registers_the_phantom(capsys):
    path = pathlib.Path(__file__).resolve().parent.parent / "examples" / "register_phantom.py"
    spec = importlib.util.spec_from_file_location("register_phantom", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    before, after, report = example.main()
    assert 4.9 < before.surface_tre_mean_mm < 5.1  # the start is 5 mm off
    assert after.surface_tre_mean_mm < 1.0, after
    assert report.ok and len(report.stages) >= 2
    # clean DRR X-rays of the CT: a right pose correlates as an X-ray of the whole CT predicts
    assert len(report.expected_view_correlations) == 3
    assert abs(report.relative_correlation - 1.0) < 0.15, report.relative_correlation
    assert "after:" in capsys.readouterr().out
