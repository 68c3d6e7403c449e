# procedures benchmarks: wall time of the shipped discrete grid against the emulator at its
# default speed-up (target < 20 s), and the controller's own time per point beyond waiting on the
# devices (target < 2 ms). Run: build/tests/bench/fpss_bench_procedures
add_executable(fpss_bench_procedures ${CMAKE_CURRENT_SOURCE_DIR}/procedures_bench.cpp)
target_link_libraries(fpss_bench_procedures PRIVATE fpss_stand_session benchmark::benchmark_main)
target_compile_definitions(fpss_bench_procedures PRIVATE FPSS_BINARY_DIR="${CMAKE_BINARY_DIR}")
target_link_libraries(fpss_bench_procedures PRIVATE fpss_test_support)
add_dependencies(fpss_bench_procedures fpss-stand)
