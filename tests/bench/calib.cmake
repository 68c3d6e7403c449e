# calib benchmark: calibrate on 2e3..2e6 samples, time and peak memory (targets: 2,000 samples
# < 50 ms, 2 million < 10 s, memory linear in samples). Run: build/tests/bench/fpss_bench_calib
add_executable(fpss_bench_calib ${CMAKE_CURRENT_SOURCE_DIR}/calib_bench.cpp)
target_link_libraries(fpss_bench_calib PRIVATE fpss_calib benchmark::benchmark_main)
