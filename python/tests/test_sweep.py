"""Sweeps of scene variants over Dask: a local cluster, a scheduler's address, failed rows.

Apart from the other workflows because a local cluster takes both cores (CTest runs this file
alone)."""

import incise

SAG_SCENE = {
    "mesh": {"box": {"cells": [3, 3, 3], "size": [0.1, 0.1, 0.1]}},
    "material": {"young_modulus": 3000, "poisson_ratio": 0.45, "density": 1000},
    "model": {"type": "corotational-fem"},
    "integrator": {"type": "backward-euler", "dt": 0.01},
    "fixed": [{"box": [[-1, -1, -1], [1, 1, 0.0001]]}],
    "gravity": [0, 0, -9.81],
    "frames": 15,
}


def test_a_sweep_on_a_local_cluster_equals_running_the_variants_here():
    variants = {"material.young_modulus": [2000.0, 4000.0], "integrator.dt": [0.01, 0.02]}
    distributed = incise.sweep(SAG_SCENE, variants, workers=2, progress=False, keep_mesh=True)
    here = incise.sweep(SAG_SCENE, variants, workers=0, progress=False)
    assert len(distributed) == 4 and distributed["error"].isna().all()
    state = ["material.young_modulus", "integrator.dt", "frames", "time", "vertices", "tets",
             "kinetic_energy", "max_displacement", "inverted_tets"]
    assert distributed[state].equals(here[state])
    assert all(p.shape == (64, 3) for p in distributed["positions"])  # the final meshes came back
    # Stiffer tissue sags less.
    soft = distributed[(distributed["material.young_modulus"] == 2000.0) & (distributed["integrator.dt"] == 0.01)]
    stiff = distributed[(distributed["material.young_modulus"] == 4000.0) & (distributed["integrator.dt"] == 0.01)]
    assert float(soft["max_displacement"].iloc[0]) > float(stiff["max_displacement"].iloc[0])
    # And each row is what a Simulation of that variant gives.
    sim = incise.Simulation(dict(SAG_SCENE, integrator={"type": "backward-euler", "dt": 0.02},
                                 material={"young_modulus": 4000.0, "poisson_ratio": 0.45,
                                           "density": 1000}))
    last = sim.step(15)[-1]
    row = here[(here["material.young_modulus"] == 4000.0) & (here["integrator.dt"] == 0.02)]
    assert float(row["max_displacement"].iloc[0]) == last.max_displacement


def test_a_sweep_through_a_scheduler_address():
    import distributed

    # A scheduler reached by its address, as one on another machine would be.
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        table = incise.sweep(SAG_SCENE, {"integrator.dt": [0.01, 0.02]},
                             scheduler=cluster.scheduler_address, frames=5, progress=False)
    here = incise.sweep(SAG_SCENE, {"integrator.dt": [0.01, 0.02]}, workers=0, frames=5,
                        progress=False)
    assert table["error"].isna().all()
    assert table["max_displacement"].tolist() == here["max_displacement"].tolist()


def test_a_failed_variant_is_a_row_not_the_end_of_the_sweep():
    table = incise.sweep(SAG_SCENE, [{"integrator.dt": 0.01}, {"integrator.dtt": 0.01},
                                     {"material.young_modulus": -5.0}], workers=0, progress=False)
    assert table["error"].iloc[0] is None
    assert "dtt" in table["error"].iloc[1]
    assert "InputError" in table["error"].iloc[2]
