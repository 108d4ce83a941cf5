// Everything the solvers' .inl files need, included once outside the backend namespace.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>

#include "boundary.h"
#include "core/atomics.h"
#include "integrate.h"
#include "interaction.h"
#include "nsearch/grid.h"
#include "dfsph.h"
#include "pbf.h"
#include "skin.h"
#include "solver.h"
