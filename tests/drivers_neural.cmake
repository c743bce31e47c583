# Quick twins of validate_neural and bench_neural (LibTorch builds only): one law, one fitted
# nu (short fit, looser stress target) and one generator nu not in its dataset; the kernel
# benchmark on a small batch must report that the fused kernel matches LibTorch.
if(GEN4D_HAVE_TORCH)
  gen4d_driver_twin(validate_neural_quick validate_neural "1"
                    ARGS --laws stvk --nu 0.3 --steps 600 --lbfgs-steps 60 --max-stress 0.02
                         --gen-nu 0.27 --finetune-steps 60
                         --generator ${CMAKE_SOURCE_DIR}/inputs/models/generator.h5)
  gen4d_driver_twin(bench_neural_quick bench_neural "1" ARGS --points 4096 --seconds 0.05
                    PASS "\"match\": true")
endif()
