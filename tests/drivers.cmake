# Small twins of the validation drivers and benchmarks (full runs: see drivers/ and README).
# Each twin runs its driver at a reduced size and must meet the driver's own target.
# Static cantilever vs Euler-Bernoulli at H/2 and H/4 (3 % target at H/4), both solvers.
gen4d_driver_twin(validate_analytic_quick validate_analytic "1;2"
                  ARGS --static-levels 2,4 --skip-frequency)
# Large time step on a coarse soft beam: stability table and ElastoGen vs Newton <= 1 %.
gen4d_driver_twin(validate_timestep_quick validate_timestep "1;2"
                  ARGS --voxel 0.025 --end-time 0.1 --skip-fine)
# ElastoGen vs Newton time per frame on a small beam: must print its JSON.
gen4d_driver_twin(bench_solvers_quick bench_solvers "1;2" ARGS --cells 4 --frames 3
                  PASS "\"speedup_elastogen_over_newton\": [0-9]")
