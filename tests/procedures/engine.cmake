# The procedure engine's tests. Included from tests/procedures/CMakeLists.txt.
fpss_add_test(procedures/procedure UNIT LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/check_report UNIT LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/engine_clock UNIT LIBS fpss_procedures INTERNALS fpss_procedures LABELS procedures)
fpss_add_test(procedures/recorder UNIT LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/design_procedure LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/engine UNIT LIBS fpss_procedures fpss_test_fakes LABELS procedures TIMEOUT 300)
fpss_add_test(procedures/adaptive_stop UNIT LIBS fpss_procedures fpss_test_fakes LABELS procedures)
fpss_add_test(procedures/events UNIT LIBS fpss_procedures fpss_test_fakes LABELS procedures)
# The engine with the real drivers against the emulated bench over the real wire.
fpss_add_test(procedures/engine_on_emulator LIBS fpss_procedures fpss_fixtures fpss_drivers PkgConfig::MODBUS
              LABELS procedures emulated TIMEOUT 300)
