"""The loci the recorded channels cannot tell apart, and how an answer names them.

The supply and the motor's electrics reach the record only through the electromagnetic torque
(``engine.simulation.parameters.LOCUS_GROUPS``): an additive electromagnetic torque reproduces a
supply deviation's change on every channel, so the locus answer names the two together and the
scorer counts the group.
"""

from __future__ import annotations

import numpy as np

from engine.constants import CHANNELS
from engine.diagnosis.locus._report import LocusReport
from engine.records import SampleGrid
from engine.simulation import Case, Disturbance, PlantParameters, simulate_batch
from engine.simulation.parameters import LOCUS_GROUPS, locus_group, locus_group_name
from engine.validation.score import Answer

NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)
M_EL = CHANNELS.index("m_el")


def test_an_electromagnetic_torque_reproduces_a_supply_deviation_on_every_channel() -> None:
    """The change a supply deviation makes, reproduced by the additive torque that gives its m_el.

    The torque is found by a fixed point on m_el alone while the motor is on (knots every t_e / 249
    from switch-on to the switch-off, where the input's last knot sits): the channels it never saw,
    the motor's speed and acceleration and the load's, follow. What is left is the input's ramp
    over one knot spacing after the switch-off and the knots' interpolation: under 2 % of the change's
    sum of squares on each channel, and under 0.5 % on the load's.
    """
    grid = SampleGrid(sample_interval=2.5e-5, n_samples=12000, event_index=1400)  # from switch-on
    supply = Disturbance("supply", 0.0, 1e-3, tuple(0.08 * np.sin(2 * np.pi * 60e-3 * np.arange(40))))
    res = simulate_batch([Case(NOMINAL), Case(NOMINAL.replace(disturbance=supply))], grid=grid)
    base, target = res.channels
    t_e = float(res.event_times[1])
    dk = t_e / 249
    knots = dk * np.arange(250)

    def m_el(channels: np.ndarray, event: float) -> np.ndarray:
        return np.interp(knots, grid.time + event, channels[M_EL])

    d = m_el(target, t_e) - m_el(base, float(res.event_times[0]))
    for _ in range(3):
        case = Case(NOMINAL.replace(disturbance=Disturbance("motor_electrical", 0.0, dk, tuple(d))))
        out = simulate_batch([case], grid=grid)
        d = d - (m_el(out.channels[0], float(out.event_times[0])) - m_el(target, t_e))
    window = grid.time > -4.8e-3  # the protocol's record
    change = (target - base)[:, window]
    left = (out.channels[0] - target)[:, window]
    share = np.sum(left**2, axis=1) / np.sum(change**2, axis=1)
    assert np.all(share < 0.02), dict(zip(CHANNELS, share.round(4), strict=True))
    assert share[CHANNELS.index("a2")] < 5e-3 and share[CHANNELS.index("v2")] < 5e-3
    assert np.all(np.sum(change**2, axis=1) > 0)  # the deviation does change every channel
    assert abs(float(out.event_times[0]) - t_e) < 1e-6


def test_the_groups_name_their_members() -> None:
    assert locus_group("supply") == ("supply", "motor_electrical")
    assert locus_group("motor_electrical") == ("motor_electrical", "supply")
    assert locus_group("load") == ("load",)
    assert locus_group_name("load") is None
    name = locus_group_name("supply")
    assert name is not None and LOCUS_GROUPS[name] == ("supply", "motor_electrical")


def _report(locus: str, group: list[str]) -> LocusReport:
    return LocusReport(
        locus=locus, scores={}, term=None, confidence=0.9, ties=[], chi2=1.0, chi2_injected=1.0,
        n_data=10, n_simulations=0, seconds=0.0, group=group,
    )  # fmt: skip


def test_the_report_states_its_group() -> None:
    d = _report("supply", ["supply", "motor_electrical"]).to_dict()
    assert d["group"] == ["supply", "motor_electrical"] and d["group_name"] == locus_group_name("supply")
    d = _report("load", ["load"]).to_dict()
    assert d["group"] == ["load"] and d["group_name"] is None


def test_the_scorer_counts_the_group_and_apart_the_single_locus() -> None:
    a = Answer("unexplained", (), "supply", 1.0, None, None, locus_group=("supply", "motor_electrical"))
    assert a.names_locus("motor_electrical") and a.names_locus("supply") and not a.names_locus("load")
    old = Answer("unexplained", (), "supply", 1.0, None, None)  # written before the groups: the locus alone
    assert old.names_locus("supply") and not old.names_locus("motor_electrical")
    assert not Answer("no_gap", (), None, 1.0, None, None).names_locus("load")
