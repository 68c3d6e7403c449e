// Must not compile: calib/ is numbers only and its target does not see the drivers.
#include "drivers/gimbal.h"

int main() { return 0; }
