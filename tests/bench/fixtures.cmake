# fixtures benchmarks: the emulated sensor sustains 200 frames/s of bench time at --speed 50
# (10,000 frames per wall second read off the pty), and a bare libmodbus read against the
# emulated gimbal. Run: build/tests/bench/fpss_bench_fixtures
add_executable(fpss_bench_fixtures ${CMAKE_CURRENT_SOURCE_DIR}/fixtures_bench.cpp)
target_link_libraries(fpss_bench_fixtures PRIVATE fpss_fixtures benchmark::benchmark_main)
