// A method that reaches into another method.
#include "engine/frontend/frame_runner.h"
#include "engine/methods/cells_internal.h"
