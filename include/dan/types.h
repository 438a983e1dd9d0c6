/* Names of the registered peripheral types, for tools and logs. */
#ifndef DAN_TYPES_H
#define DAN_TYPES_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *name; /* short name for command lines ("can-gw") */
    uint32_t first;   /* first code of the block (IDENTIFY) */
    const char *title;
    uint8_t blocks; /* consecutive blocks of 16 codes it owns */
} dan_type_info_t;

/* The registry in code order; ends with a NULL name. */
extern const dan_type_info_t dan_type_registry[];

/* Looks a type up by short name or by its first code written as a number
 * ("0x40"); NULL if unknown. */
const dan_type_info_t *dan_type_lookup(const char *name_or_code);

/* The type whose blocks hold code, or NULL. */
const dan_type_info_t *dan_type_of_code(uint32_t code);

#ifdef __cplusplus
}
#endif

#endif /* DAN_TYPES_H */
