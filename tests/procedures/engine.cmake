# The procedure engine's tests. Included from tests/procedures/CMakeLists.txt.
fpss_add_test(procedures/procedure LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/recorder LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/engine LIBS fpss_stand_session LABELS procedures TIMEOUT 300)
add_dependencies(procedures_engine_test fpss-stand)
