#include "core/evaluation.h"
