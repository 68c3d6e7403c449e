# catalogue benchmarks: write latency p50/p99 with 1, 4 and 16 concurrent writer processes on both
# backends (a real SQLite file, a real PostgreSQL 15 server started for the run), and `history` of a
# unit with 1,000 calibrations. Figures in docs/fleet.md. Run: build/tests/bench/fpss_bench_catalogue
add_executable(fpss_bench_catalogue ${CMAKE_CURRENT_SOURCE_DIR}/catalogue_bench.cpp)
target_link_libraries(fpss_bench_catalogue PRIVATE fpss_stand_catalogue fpss_test_support benchmark::benchmark_main)
target_compile_definitions(fpss_bench_catalogue PRIVATE FPSS_BINARY_DIR="${CMAKE_BINARY_DIR}")
target_link_libraries(fpss_bench_catalogue PRIVATE fpss_test_support)
add_dependencies(fpss_bench_catalogue fpss-stand)
