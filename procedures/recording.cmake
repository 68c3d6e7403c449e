# procedures/recording: the run catalogue (SQLite) and the run report (report.html). Included by
# procedures/CMakeLists.txt; the engine's library links fpss_recording.
add_library(fpss_recording
  ${CMAKE_CURRENT_LIST_DIR}/catalogue.cpp
  ${CMAKE_CURRENT_LIST_DIR}/report.cpp
  ${CMAKE_CURRENT_LIST_DIR}/report_plot.cpp
)
target_include_directories(fpss_recording PUBLIC ${PROJECT_SOURCE_DIR})
target_link_libraries(fpss_recording PUBLIC fpss_calib SQLiteCpp fmt::fmt nlohmann_json::nlohmann_json)
