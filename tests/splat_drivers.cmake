# Small twin of the splat rotation driver: both solvers turn the donut (SH 3) 60 degrees, and
# each rendering matches the counter-rotated camera's (>= 35 dB) while the ablations score lower.
gen4d_driver_twin(validate_splat_rotation_quick validate_splat_rotation "2"
                  ARGS --quick --out splat_rotation_quick)
