#include "core/rig.h"
