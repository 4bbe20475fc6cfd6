"""Fleet calibration: one calibration config mapped over many units on Dask, one Parquet table of
results, outliers and drift across units (docs/fleet.md).

  manifest  fleet.yaml and its units (manifest CSV or glob), input and config hashes
  unit      one unit's calibration, run on a worker: output folder + table row
  table     the Parquet fleet table (schema, atomic write, resume)
  runner    fleet run: submit, stream rows to the table as units finish
  report    distribution, median/MAD outliers and drift across units
  page      the HTML page of a fleet report
  synthetic simulated fleets (tests, benchmarks, examples)

Dask and pyarrow are the optional [fleet] extra: they are imported inside the functions that need them,
and the cluster itself comes from robocal.estimation.parallel_map.
"""
from robocal.workflows.fleet.manifest import FleetSpec, UnitJob, load_fleet
from robocal.workflows.fleet.page import fleet_page
from robocal.workflows.fleet.report import FleetReport, fleet_report
from robocal.workflows.fleet.runner import FleetRun, run_fleet
from robocal.workflows.fleet.synthetic import SimulatedFleet, simulated_fleet

__all__ = ["FleetSpec", "UnitJob", "load_fleet", "fleet_page", "FleetReport", "fleet_report", "FleetRun",
           "run_fleet", "SimulatedFleet", "simulated_fleet"]
