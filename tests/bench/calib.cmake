# calib benchmark: calibrate on 2e3..2e6 samples, time and peak memory (targets: 2,000 samples
# < 50 ms, 2 million < 10 s, memory linear in samples). Run: build/tests/bench/fpss_bench_calib
add_executable(fpss_bench_calib ${CMAKE_CURRENT_SOURCE_DIR}/calib_bench.cpp)
target_link_libraries(fpss_bench_calib PRIVATE fpss_calib benchmark::benchmark_main)

# calib statistics: Monte Carlo on the independent Python generator (tests/gen/grid_gen.py) for
# three published truths: efficiency against the design's Cramer-Rao bound, coverage of the
# reported 1-sigma, long-dwell quantisation floor. Run: build/tests/bench/fpss_bench_calib_stats
add_executable(fpss_bench_calib_stats ${CMAKE_CURRENT_SOURCE_DIR}/calib_stats_bench.cpp)
target_link_libraries(fpss_bench_calib_stats PRIVATE fpss_calib fmt::fmt benchmark::benchmark_main)
target_link_libraries(fpss_bench_calib_stats PRIVATE fpss_test_support)
target_compile_definitions(fpss_bench_calib_stats PRIVATE FPSS_SOURCE_DIR="${FPSS_SOURCE_DIR}"
                           FPSS_BINARY_DIR="${CMAKE_BINARY_DIR}")
