# fixtures benchmarks: the emulated sensor sustains 200 frames/s of bench time at --speed 50
# (10,000 frames per wall second read off the pty), and a bare libmodbus read against the
# emulated gimbal, and a soak: `fpss-stand emulate` serving 8 random clients and a flood of 2,000
# connects for FPSS_SOAK_S seconds (default 20). Run: build/tests/bench/fpss_bench_fixtures
# (FPSS_SOAK_S=600 build/tests/bench/fpss_bench_fixtures --benchmark_filter=Soak for the 10-minute soak)
add_executable(fpss_bench_fixtures ${CMAKE_CURRENT_SOURCE_DIR}/fixtures_bench.cpp)
target_link_libraries(fpss_bench_fixtures PRIVATE fpss_fixtures benchmark::benchmark_main)
target_compile_definitions(fpss_bench_fixtures PRIVATE FPSS_BINARY_DIR="${CMAKE_BINARY_DIR}")
add_dependencies(fpss_bench_fixtures fpss-stand)
