"""Fleet calibration: one calibration config mapped over many units on Dask, one Parquet table of
results, outliers and drift across units (docs/fleet.md).

  manifest  fleet.yaml and its units (manifest CSV or glob), input and config hashes
  unit      one unit's calibration, run on a worker: output folder + table row
  table     the Parquet fleet table (schema, atomic write, resume)
  engine    the Dask client (LocalCluster or a scheduler address) and map_tasks
  runner    fleet run: submit, stream rows to the table as units finish
  report    distribution, median/MAD outliers and drift across units
  page      the HTML page of a fleet report
  synthetic simulated fleets (tests, benchmarks, examples)

Dask and pyarrow are the optional [fleet] extra: they are imported inside the functions that need them.
"""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "runner": "FleetRun run_fleet", "manifest": "FleetSpec UnitJob load_fleet", "engine": "map_tasks",
    "report": "FleetReport fleet_report", "page": "fleet_page", "synthetic": "SimulatedFleet simulated_fleet"})
