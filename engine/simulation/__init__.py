"""Simulator of the reference plant (MODEL.md) and its backlash test."""

from engine.simulation.effects import CATALOGUE, LOCI, Effect, EffectLibrary, Locus, UnknownEffectError, apply_effects
from engine.simulation.held_back import HELD_BACK
from engine.simulation.held_out import HELD_OUT
from engine.simulation.noise import add_white_noise, noise_std
from engine.simulation.parameters import (
    DISTURBANCE_LOCI,
    Case,
    Disturbance,
    ParameterError,
    PlantParameters,
    SensorParameters,
    SolverSettings,
    full_grid,
    paper_grid,
)
from engine.simulation.sealed import SEALED
from engine.simulation.sealed2 import SEALED2
from engine.simulation.sealed3 import SEALED3
from engine.simulation.sealed4 import SEALED4
from engine.simulation.sealed5 import SEALED5
from engine.simulation.simulator import (
    SimulationError,
    SimulationResult,
    run_cases,
    serial_kernel,
    simulate,
    simulate_batch,
)

__all__ = [
    "CATALOGUE",
    "DISTURBANCE_LOCI",
    "HELD_BACK",
    "HELD_OUT",
    "LOCI",
    "SEALED",
    "SEALED2",
    "SEALED3",
    "SEALED4",
    "SEALED5",
    "Case",
    "Disturbance",
    "Effect",
    "EffectLibrary",
    "Locus",
    "ParameterError",
    "PlantParameters",
    "SensorParameters",
    "SimulationError",
    "SimulationResult",
    "SolverSettings",
    "UnknownEffectError",
    "add_white_noise",
    "apply_effects",
    "full_grid",
    "noise_std",
    "paper_grid",
    "run_cases",
    "serial_kernel",
    "simulate",
    "simulate_batch",
]
