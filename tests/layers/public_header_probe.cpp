// Compiles: the engine is part of fpss_procedures' public interface (the control for the probe beside it).
#include "procedures/engine.h"

int main() { return 0; }
