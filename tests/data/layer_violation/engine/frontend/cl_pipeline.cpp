// The front end that depends on the cells machinery, which only the cells method owns.
#include "engine/features/batching.h"
#include "engine/cells/cell_order.h"
