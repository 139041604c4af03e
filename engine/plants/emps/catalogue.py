"""Candidate unmodelled effects of the EMPS axis: each one scalar, each at one locus.

Loci of this plant (:data:`LOCI`): ``drive`` (amplifier and motor: the force the command
produces), ``guide`` (friction of the carriage on its guides and of the screw-nut),
``transmission`` (the ball screw between motor and carriage), ``load`` (forces on the carriage
from outside the drive, e.g. cables), ``sensors`` (the encoder chain).

Each effect sets one field of :class:`~engine.plants.emps.model.EmpsParameters`; its neutral
value is the published rigid model. The fixed parts of multi-parameter effects are documented
choices (:data:`engine.plants.emps.model.STRIBECK_VELOCITY`, ``FLEX_MASS_RATIO``,
``FLEX_DAMPING_RATIO``, ``POSITION_FRICTION_PERIOD``).

The **held-back family** (:data:`HELD_BACK`, issue 52): one effect per locus outside the
catalogue, for scoring the diagnosis of a gap the catalogue cannot explain. The plant simulates
them (:data:`HELD_BACK_FIELDS`); the diagnosis never fits them. They were fixed before any locus
estimate existed and are not tuned to one.

The **sealed family** (:data:`SEALED`): one more effect per locus, outside the catalogue and the
held-back family, kept for scoring a diagnosis **once**. Defined before any diagnosis ran on
them; development never reads their scores; a blind run scores them once. The plant simulates
them (:data:`SEALED_FIELDS`); nothing else here knows them. Their fixed parts are documented
constants of :mod:`engine.plants.emps.model` (``CONTAMINATION_POSITION``,
``CONTAMINATION_WIDTH``, ``VIBRATION_FREQUENCY``, ``SLIP_SHARE``).
"""

from __future__ import annotations

from engine.plants.base import CandidateEffect

__all__ = ["CATALOGUE", "EFFECT_FIELDS", "HELD_BACK", "HELD_BACK_FIELDS", "LOCI", "SEALED", "SEALED_FIELDS"]

#: The parts of the EMPS axis where an effect may act (module docstring).
LOCI: tuple[str, ...] = ("drive", "guide", "transmission", "load", "sensors")

#: name -> field of EmpsParameters the effect's scalar sets.
EFFECT_FIELDS: dict[str, str] = {
    "coulomb_asymmetry": "dFc",
    "viscous_asymmetry": "dFv",
    "stribeck": "Fs",
    "flexibility": "f_flex",
    "drive_gain": "gain_err",
    "offset_change": "d_offset",
    "position_friction": "A_pos",
    "actuator_delay": "delay",
    "command_limit": "v_sat",
}

#: The catalogue, in a fixed order.
CATALOGUE: dict[str, CandidateEffect] = {
    e.name: e
    for e in (
        CandidateEffect(
            "coulomb_asymmetry",
            "Coulomb friction that differs with the direction of motion: Fc + dFc moving forward, "
            "Fc - dFc backward (Janot et al. 2017, the authors' eq. 12); scalar dFc [N].",
            (-15.0, 15.0),
            0.0,
            "N",
            "guide",
        ),
        CandidateEffect(
            "viscous_asymmetry",
            "Viscous friction that differs with the direction: Fv + dFv forward, Fv - dFv backward; scalar dFv [N s/m].",
            (-80.0, 80.0),
            0.0,
            "N s/m",
            "guide",
        ),
        CandidateEffect(
            "stribeck",
            "Stribeck friction: an extra Fs exp(-(v / v_s)^2) sign(v) at low speed (v_s fixed, see the model); "
            "scalar Fs [N].",
            (-20.0, 40.0),
            0.0,
            "N",
            "guide",
        ),
        CandidateEffect(
            "flexibility",
            "A flexible transmission: the mass split into motor side and carriage behind a spring and damper "
            "(mass ratio and damping ratio fixed, see the model); scalar: the natural frequency f [Hz] "
            "(neutral 0 = rigid).",
            (5.0, 200.0),
            0.0,
            "Hz",
            "transmission",
            log=True,
        ),
        CandidateEffect(
            "drive_gain",
            "Drive gain error: the force is g_tau (1 + eps) v while the force channel still reads g_tau v; "
            "scalar eps [-].",
            (-0.25, 0.25),
            0.0,
            "",
            "drive",
        ),
        CandidateEffect(
            "offset_change",
            "A change of the constant force offset since the calibration; scalar d_offset [N]. "
            "Indistinguishable from the calibrated offset when both are fitted to one record.",
            (-15.0, 15.0),
            0.0,
            "N",
            "load",
        ),
        CandidateEffect(
            "position_friction",
            "Friction that varies with position, once per screw revolution: A sin(2 pi q / p) sign(v) "
            "(p fixed, see the model); scalar A [N].",
            (-20.0, 20.0),
            0.0,
            "N",
            "guide",
        ),
        CandidateEffect(
            "actuator_delay",
            "An extra delay between the command and the force, beyond the controller's one-sample delay; "
            "scalar tau [s].",
            (0.0, 0.004),
            0.0,
            "s",
            "drive",
        ),
        CandidateEffect(
            "command_limit",
            "The level at which the controller's command saturates [V] (the published models clip it at "
            "10 V before the pulses are added); scalar v_max [V], neutral 10.",
            (5.0, 20.0),
            10.0,
            "V",
            "drive",
        ),
    )
}

#: name -> field of EmpsParameters a held-back effect's scalar sets.
HELD_BACK_FIELDS: dict[str, str] = {
    "amplifier_dead_band": "dead_band",
    "quadratic_drag": "c_quad",
    "screw_force_ripple": "A_ripple",
    "cable_spring": "k_cable",
    "position_log_skew": "log_skew",
}

#: The held-back family: one effect per locus, outside the catalogue (module docstring).
HELD_BACK: dict[str, CandidateEffect] = {
    e.name: e
    for e in (
        CandidateEffect(
            "amplifier_dead_band",
            "An amplifier dead band: no force for commands below v0 in magnitude, the force "
            "g_tau dz(v, v0) with dz(v, v0) = sign(v) max(|v| - v0, 0) applied to the command after "
            "delay, saturation and pulse, while the force channel still reads g_tau v; scalar v0 [V].",
            (0.05, 0.5),
            0.0,
            "V",
            "drive",
        ),
        CandidateEffect(
            "quadratic_drag",
            "A friction growing with the square of the speed on the motor side, c_q v |v| opposing the "
            "motion; scalar c_q [N s^2/m^2].",
            (20.0, 400.0),
            0.0,
            "N s^2/m^2",
            "guide",
        ),
        CandidateEffect(
            "screw_force_ripple",
            "A force ripple once per screw revolution on the motor side, A sin(2 pi q / p) counted "
            "opposing the drive whatever the direction of motion (no sign(v), unlike "
            "position_friction; p the same period, see the model); scalar A [N].",
            (-10.0, 10.0),
            0.0,
            "N",
            "transmission",
        ),
        CandidateEffect(
            "cable_spring",
            "A cable carrier pulling the carriage back towards q = 0 with the force k_c q (q the "
            "motor-side position); scalar k_c [N/m].",
            (50.0, 500.0),
            0.0,
            "N/m",
            "load",
        ),
        CandidateEffect(
            "position_log_skew",
            "A skew of the data logger: the logged position lags the logged force by delta (the loop "
            "is unchanged; the recorded qm is the true position delayed by delta, linearly "
            "interpolated on the sample grid); scalar delta [s].",
            (0.0005, 0.003),
            0.0,
            "s",
            "sensors",
        ),
    )
}

#: name -> field of EmpsParameters a sealed effect's scalar sets.
SEALED_FIELDS: dict[str, str] = {
    "drive_gain_asymmetry": "gain_asym",
    "guide_contamination": "F_contam",
    "screw_load_friction": "mu_screw",
    "load_vibration": "A_vib",
    "encoder_slip": "slip",
}

#: The sealed family: one effect per locus, scored once (module docstring).
SEALED: dict[str, CandidateEffect] = {
    e.name: e
    for e in (
        CandidateEffect(
            "drive_gain_asymmetry",
            "The amplifier's gain differs with the command's sign: the force is "
            "g_tau (1 + eps sign(v)) v, v the command after delay, saturation, pulse and dead band, "
            "while the force channel still reads g_tau v; scalar eps [-].",
            (0.03, 0.15),
            0.0,
            "",
            "drive",
        ),
        CandidateEffect(
            "guide_contamination",
            "A contaminated stretch of the guide: an extra friction F_d exp(-((q - q_d) / w_d)^2) sign(v) "
            "on the motor side (q_d = 0.125 m, the middle of DATA_EMPS's travel, and w_d = 0.02 m, "
            "see the model); scalar F_d [N].",
            (3.0, 15.0),
            0.0,
            "N",
            "guide",
        ),
        CandidateEffect(
            "screw_load_friction",
            "The ball screw's friction grows with the axial load it transmits: an extra friction "
            "mu |F| sign(v) on the motor side, F the drive's force (after gain error, dead band and "
            "gain asymmetry; without the external force); scalar mu [-].",
            (0.02, 0.1),
            0.0,
            "",
            "transmission",
        ),
        CandidateEffect(
            "load_vibration",
            "Floor vibration: an external force A sin(2 pi f_v t) on the carriage, positive forward "
            "(f_v = 8 Hz, see the model; t from the record's first sample, held over each sample "
            "interval); scalar A [N].",
            (2.0, 10.0),
            0.0,
            "N",
            "load",
        ),
        CandidateEffect(
            "encoder_slip",
            "The data logger's position count jumps once: the recorded position gains a permanent step "
            "Delta at 40 % of the record's duration (the loop is unchanged); scalar Delta [m].",
            (2e-6, 1e-5),
            0.0,
            "m",
            "sensors",
        ),
    )
}
