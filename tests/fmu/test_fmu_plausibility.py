"""A record the plant cannot have produced gets a warning that names the suspicion (issue 50 item 3, for
every plant: :mod:`engine.diagnosis.plant_plausibility`), shown here on the quarter-car FMU plant."""

from __future__ import annotations

import numpy as np
import pytest

from engine.diagnosis.plant_gap import diagnose_plant
from engine.diagnosis.plant_plausibility import ConstantChannelError, interval_evidence
from engine.plants.fmu import EXAMPLES_DIR, FmuPlant, load_plant
from engine.plants.fmu.record import FmuRecord


@pytest.fixture(scope="module")
def plant(tmp_path_factory: pytest.TempPathFactory) -> FmuPlant:
    return load_plant(EXAMPLES_DIR / "quarter_car" / "plant.toml", tmp_path_factory.mktemp("plaus"), processes=1)


def _rig_test(plant: FmuPlant, seconds: float = 0.6) -> FmuRecord:
    """A synthetic rig test of the model itself (calibrated parameters off nominal), its first ``seconds``."""
    record = plant.synthesize(plant.example(), {"m_s": 320.0}, np.random.default_rng(11))
    keep = record.t < seconds
    return FmuRecord(record.name, record.t[keep], {k: np.asarray(v)[keep] for k, v in record.columns.items()})


def test_units_mistaken_on_two_channels_are_named(plant: FmuPlant) -> None:
    """x_susp in mm and a_body in g, both declared as the model's m and m/s^2: each channel's warning names the
    factor and the unit to check; the clean channel gets none."""
    clean = _rig_test(plant)
    columns = dict(clean.columns)
    columns["x_susp"] = 1e3 * columns["x_susp"]  # mm
    columns["a_body"] = columns["a_body"] / 9.80665  # g
    answer = diagnose_plant(plant, FmuRecord("units", clean.t, columns), jobs=1).to_dict(plant)
    by_channel = {w["channel"]: w for w in answer["warnings"]}
    assert by_channel["x_susp"]["code"] == "channel_scale" and "milli-units" in by_channel["x_susp"]["message"]
    assert by_channel["a_body"]["code"] == "channel_scale" and "in g where m/s^2" in by_channel["a_body"]["message"]
    assert by_channel.get("a_wheel", {"code": "misfit"})["code"] == "misfit"  # its fit is distorted, its scale right


def test_a_record_of_the_model_gets_no_warning(plant: FmuPlant) -> None:
    answer = diagnose_plant(plant, _rig_test(plant), jobs=1).to_dict(plant)
    assert answer["status"] == "no_gap" and answer["warnings"] == []


def test_a_constant_channel_is_refused_before_any_fit(plant: FmuPlant) -> None:
    clean = _rig_test(plant, seconds=0.2)
    columns = {**clean.columns, "a_wheel": np.full(clean.n, 0.5)}
    with pytest.raises(ConstantChannelError, match=r"channel a_wheel is 0\.5 m/s2 at every one of its"):
        diagnose_plant(plant, FmuRecord("stuck", clean.t, columns), jobs=1)


def test_a_sample_interval_declared_ten_times_too_long_is_named(plant: FmuPlant) -> None:
    """The rig test's time column read as 10 ms for its 1 ms samples: the answer warns `sample_interval`, names
    the reading that fits (1 ms) and still warns of the misfit; as declared rightly, the statistic is far below it."""
    clean = _rig_test(plant, seconds=0.3)
    wrong = plant.retimed(clean, 10.0)
    assert np.allclose(np.diff(wrong.t), 10 * np.diff(clean.t)) and wrong.t[0] == clean.t[0]
    answer = diagnose_plant(plant, wrong, jobs=1).to_dict(plant)
    codes = [w["code"] for w in answer["warnings"]]
    assert "sample_interval" in codes and "misfit" in codes, codes
    message = next(w["message"] for w in answer["warnings"] if w["code"] == "sample_interval")
    assert "10x slower" in message and "0.001 s instead of the declared 0.01 s" in message
    evidence, _ = interval_evidence(plant, clean, [{"m_s": 320.0}, {}], plant.noise(clean))
    assert evidence < 1.0  # the right reading: no other fits better
