#include "core/camera_model.h"
