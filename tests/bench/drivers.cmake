# drivers benchmarks: gimbal state read vs a bare libmodbus read on loopback (ratio, target <= 1.2x),
# frame parser throughput (target >= 50 MB/s). Run: build/tests/bench/fpss_bench_drivers
add_executable(fpss_bench_drivers
  ${CMAKE_CURRENT_SOURCE_DIR}/drivers_bench.cpp
  ${PROJECT_SOURCE_DIR}/tests/drivers/modbus_test_server.cpp)
target_include_directories(fpss_bench_drivers PRIVATE ${PROJECT_SOURCE_DIR}/tests/drivers)
target_link_libraries(fpss_bench_drivers PRIVATE fpss_drivers_internals fpss_test_support PkgConfig::MODBUS util benchmark::benchmark_main)
