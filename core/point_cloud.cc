#include "core/point_cloud.h"
