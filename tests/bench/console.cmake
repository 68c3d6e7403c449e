# console benchmark: a run's wall time alone and under `fpss-stand serve` with a live event stream
# attached (target: at most 5 % more). Run: build/tests/bench/fpss_bench_console
add_executable(fpss_bench_console ${CMAKE_CURRENT_SOURCE_DIR}/console_bench.cpp)
target_link_libraries(fpss_bench_console PRIVATE PkgConfig::HTTPLIB nlohmann_json::nlohmann_json benchmark::benchmark_main
                      Threads::Threads)
target_compile_definitions(fpss_bench_console PRIVATE FPSS_BINARY_DIR="${CMAKE_BINARY_DIR}")
target_link_libraries(fpss_bench_console PRIVATE fpss_test_support)
add_dependencies(fpss_bench_console fpss-stand)
