/* libdan: the DAN v1 (Drone Area Network) protocol library. Umbrella header. */
#ifndef DAN_DAN_H
#define DAN_DAN_H

#include "dan/config.h"
#include "dan/common.h"
#include "dan/codes.h"
#include "dan/frame.h"
#include "dan/payloads.h"
#include "dan/link.h"
#include "dan/master.h"
#include "dan/peripheral.h"
#include "dan/types.h"

#endif
