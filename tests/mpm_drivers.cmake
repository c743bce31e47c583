# Small twins of the MPM validation drivers and benchmark (full runs: drivers/validation and the
# README). Each twin meets its driver's own target at a reduced size.
# Elastic bar: first axial frequency within 3 %, momentum conserved to 1e-10.
gen4d_driver_twin(validate_mpm_bar_quick validate_mpm_bar "1;2" ARGS --cells 20 --periods 2)
# Taylor impact: the first Wilkins & Guinan copper rod (89 m/s), Lf within 5 %.
gen4d_driver_twin(validate_mpm_taylor_quick validate_mpm_taylor "1;2"
                  ARGS --series cu_wilkins --max-tests 1 --radius-cells 4)
# The collapse and slump drivers miss their targets at full resolution (README), so they have
# no twin that could pass by a coarse grid's luck; test_mpm covers their materials and walls.
# Benchmark: must run and print its JSON at 1 and 2 ranks.
gen4d_driver_twin(bench_mpm_quick bench_mpm "1;2"
                  ARGS --particles 20000 --substeps 3 --stream-n 1000000
                  PASS "\"particle_substeps_per_s\": [0-9]")
