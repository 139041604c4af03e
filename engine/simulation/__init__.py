"""Simulator of the reference plant (MODEL.md) and its backlash test."""

from engine.simulation.effects import CATALOGUE, Effect, EffectLibrary, UnknownEffectError, apply_effects
from engine.simulation.noise import add_white_noise, noise_std
from engine.simulation.parameters import (
    Case,
    ParameterError,
    PlantParameters,
    SensorParameters,
    SolverSettings,
    full_grid,
    paper_grid,
)
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
    "Case",
    "Effect",
    "EffectLibrary",
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
