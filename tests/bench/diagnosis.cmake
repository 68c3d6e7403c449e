# diagnosis benchmarks: the 200-case blind check (targets: top-1 >= 95 % overall and per effect,
# false alarms on none <= 5 %, parameters within 10 %, gap_after <= 1.5x noise floor), the same
# with two effects per case (86 cases: every distinguishable pair twice), and
# diagnose on 25k..200k-row recordings (target: 100k rows < 10 s, cost linear in rows), and at
# 100k rows on backlash + time skew (BM_DiagnoseBacklashSkewRows, the same target).
# BM_ConfusableInvestigations: the active loop's confusable and unseen cases, six of each kind.
# Run: build/tests/bench/fpss_bench_diagnosis  (--benchmark_filter=Rows for the timing only)
add_executable(fpss_bench_diagnosis ${CMAKE_CURRENT_SOURCE_DIR}/diagnosis_bench.cpp)
target_link_libraries(fpss_bench_diagnosis PRIVATE fpss_stand_blindtest fpss_stand_investigate fpss_diagnosis benchmark::benchmark_main)
