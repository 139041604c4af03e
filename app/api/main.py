"""The /v1 router: one router per resource."""

from fastapi import APIRouter

from app.api.routes import diagnose, identify, jobs, pattern_sets, simulate

api_router = APIRouter()
api_router.include_router(simulate.router)
api_router.include_router(pattern_sets.router)
api_router.include_router(jobs.router)
api_router.include_router(identify.router)
api_router.include_router(diagnose.router)
