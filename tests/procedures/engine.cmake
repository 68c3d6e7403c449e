# The procedure engine's tests. Included from tests/procedures/CMakeLists.txt.
fpss_add_test(procedures/procedure LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/recorder LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/design_procedure LIBS fpss_procedures LABELS procedures)
fpss_add_test(procedures/engine LIBS fpss_procedures fpss_test_fakes LABELS procedures TIMEOUT 300)
fpss_add_test(procedures/adaptive_stop LIBS fpss_procedures fpss_test_fakes LABELS procedures)
fpss_add_test(procedures/events LIBS fpss_procedures fpss_test_fakes LABELS procedures)
