"""The /v1 router: one router per resource."""

from fastapi import APIRouter

from app.api.routes import (
    assets,
    diagnose,
    diagnoses,
    fmus,
    identifications,
    identify,
    jobs,
    maintenance,
    pattern_sets,
    plants,
    records,
    simulate,
)

api_router = APIRouter()
api_router.include_router(simulate.router)
api_router.include_router(pattern_sets.router)
api_router.include_router(jobs.router)
api_router.include_router(identify.router)
api_router.include_router(identifications.router)
api_router.include_router(diagnose.router)
api_router.include_router(diagnoses.router)
api_router.include_router(records.router)
api_router.include_router(assets.router)
api_router.include_router(fmus.router)
api_router.include_router(plants.router)
api_router.include_router(maintenance.router)
