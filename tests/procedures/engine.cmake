# The procedure engine's tests (procedure files, plans, recorder, alignment, the engine over the
# real wire against the emulator). Included from tests/procedures/CMakeLists.txt.
fpss_add_test(procedures/procedure LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/recorder LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/engine LIBS fpss_procedures LABELS procedures emulated TIMEOUT 300)
add_dependencies(procedures_engine_test fpss-stand)  # forks the binary as the emulated bench
