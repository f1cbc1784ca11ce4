#include "core/trajectory.h"
