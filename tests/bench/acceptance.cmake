# acceptance statistics: coverage of the accuracy criteria's expanded uncertainty U on recordings of
# the independent generator (tests/gen/grid_gen.py --verification), with and without reference
# errors drawn from a reference file's u. Run: build/tests/bench/fpss_bench_acceptance
add_executable(fpss_bench_acceptance ${CMAKE_CURRENT_SOURCE_DIR}/acceptance_bench.cpp)
target_link_libraries(fpss_bench_acceptance PRIVATE fpss_stand_acceptance fpss_calib_internals fmt::fmt benchmark::benchmark_main)
target_link_libraries(fpss_bench_acceptance PRIVATE fpss_test_support)
target_compile_definitions(fpss_bench_acceptance PRIVATE FPSS_SOURCE_DIR="${FPSS_SOURCE_DIR}"
                           FPSS_BINARY_DIR="${CMAKE_BINARY_DIR}")
