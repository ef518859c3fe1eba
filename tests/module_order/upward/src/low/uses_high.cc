#include "banmo/high/thing.h"
