"""Maps at scale: bifurcation diagrams, regime maps and basins of attraction computed as
batched tasks (in this process or on Dask distributed workers), written to HDF5 as they
finish, resumable, identical bit for bit wherever they ran."""

from analysis.maps.axes import Axis, AxisError
from analysis.maps.execute import (
    MapRunner,
    RunReport,
    SchedulerError,
    default_workers,
)
from analysis.maps.finish import finish_map
from analysis.maps.plan import (
    BASIN_AXES,
    KINDS,
    MapPlan,
    MapSettings,
    PlanError,
    basin_plan,
    bifurcation_plan,
    regime_plan,
)
from analysis.maps.store import MapFileError, MapStore, read_map
from analysis.maps.summary import summarize
from analysis.progress import MapProgress

__all__ = [
    "BASIN_AXES",
    "KINDS",
    "Axis",
    "AxisError",
    "MapFileError",
    "MapPlan",
    "MapProgress",
    "MapRunner",
    "MapSettings",
    "MapStore",
    "PlanError",
    "RunReport",
    "SchedulerError",
    "basin_plan",
    "bifurcation_plan",
    "default_workers",
    "finish_map",
    "read_map",
    "regime_plan",
    "summarize",
]
