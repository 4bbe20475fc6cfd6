"""Write a small simulated fleet to calibrate with `robocal fleet run` (docs/fleet.md).

    python examples/fleet/make_example.py [FOLDER]          # default: ./fleet-example
    robocal fleet run FOLDER/fleet.yaml --workers 2
    robocal fleet report FOLDER/fleet-output/fleet.parquet

12 UR5 units of 30 tracker poses: U002 has a cell that is not a number, U005 has its measurements
out of step with its joint readings (the fit fails), U009 has a true elbow offset far from the rest
(an outlier in the report). arm.yaml, units.csv and fleet.yaml are ordinary files to edit.
"""
import sys

from robocal.workflows.fleet import simulated_fleet

if __name__ == "__main__":
    folder = sys.argv[1] if len(sys.argv) > 1 else "fleet-example"
    fleet = simulated_fleet(folder, 12, samples=30, seed=3, broken=(2,), shuffled=(5,),
                            truth={9: {"elbow_joint.offset": 0.02}})
    print(f"Wrote {fleet.fleet_yaml}, {fleet.manifest}, {fleet.template} and {len(fleet.truth)} unit CSVs "
          f"(true parameters in data/*_truth.json)\n\nNext:\n  robocal fleet run {fleet.fleet_yaml} --workers 2\n"
          f"  robocal fleet report {fleet.fleet_yaml.parent / 'fleet-output' / 'fleet.parquet'}")
