// Must not compile: the engine's I/O is internal to fpss_procedures, and this target is not it.
#include "procedures/engine_io.h"

int main() { return 0; }
