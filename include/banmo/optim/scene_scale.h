// Moved to model/scene_scale.h (the scene scale is the model's); this header
// forwards to it for existing includes.
#pragma once

#include "banmo/model/scene_scale.h"
