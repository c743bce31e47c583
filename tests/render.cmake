# The 3DGS renderer (src/gaussians): analytic images, brute-force reference, the distributed
# render bit for bit at 1, 2 and 4 ranks, cameras.json and the JSON reader.
gen4d_test(render SOURCES test_render.cpp LIBS gen4d_gaussians RANKS 1 2 4)
# The renderer on a GPU against the host (skipped without a CUDA device).
gen4d_test(render_gpu SOURCES test_render_gpu.cpp LIBS gen4d_gaussians RANKS 1 2 LABELS gpu)
# gen4d render end to end on the donut (../shared/data/splats/donut): views from a cameras.json
# and an orbit at 1 and 2 ranks (identical PNGs), and bad inputs (exit 2, nothing written).
gen4d_cli_test(cli_render TIMEOUT 300
               ARGS ${GEN4D_SHARED_DIR}/data/splats/donut/point_cloud.ply)
# Benchmark: must run and print its JSON at 1 and 2 ranks (small synthetic case).
gen4d_driver_twin(bench_render_quick bench_render "1;2"
                  ARGS --splats 20000 --frames 1
                       --donut ${GEN4D_SHARED_DIR}/data/splats/donut/point_cloud.ply
                  PASS "\"identical\": true")
