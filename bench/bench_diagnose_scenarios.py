"""The diagnosis's single-effect scenarios of test/test_diagnose.py, printed (the tests only bound them).

Usage (from the repository root): .venv/bin/python bench/bench_diagnose_scenarios.py

Thesis case 16 (config/rigs/default.yaml), 60 s at the reference noise, one effect concealed
(load cells 20 ms late; 3 kg cables): the rigid-body fit, then what ``rig-identify inertia``
does under model error (pipeline.offline.with_diagnosis); per entry the error % and error/σ
before and after, the named effects with their parameters.  Quoted in docs/results.md
("Diagnosis").
"""
import sys

import yaml

from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.offline import compare_to_truth, identify_recording, with_diagnosis

for effect in ({"name": "sensor_delay", "stream": "load_cells", "delay": 0.02}, {"name": "cable_mass", "mass": 3.0}):
    d = yaml.safe_load(open("config/rigs/default.yaml"))
    d["rig"].pop("dummy_mass", None)
    d["duration"] = 60.0
    d["effects"] = [effect]
    d["sensors"]["noise"] = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5,
                             "inclinometer": 0.0002}
    sim = simulate(experiment_from_dict(d, effect["name"]))
    rec = Recording(sim.rig, sim.sensors, sim.truth)
    rigid = identify_recording(rec)
    res = with_diagnosis(rec, rigid)   # what rig-identify inertia does under model error
    print(f"== {effect}: weight_surplus {rigid.weight_surplus:+.4%}; rigid-body verdict {rigid.validation.verdict}; "
          f"after: {res.validation.verdict}")
    print("   named:", [(e["name"], e["parameters"], e.get("parameters_std"))
                         for e in (res.diagnosis or {}).get("effects", [])])
    for lab, r in (("rigid", rigid), ("after", res)):
        c = compare_to_truth(r, sim.truth)
        print(f"   {lab}: " + ", ".join(f"{k} {c[k]['error_percent']:+.3f}% ({c[k]['error_sigma']:+.2f}σ)"
                                         for k in KEYS))
    sys.stdout.flush()
