/* Includes the plugin header twice, as a plugin made of several files would, and declares the entry
 * point the way the header says; compiled as strict C99 and as C++17 with every warning an error. */
#include "skid_plugin.h"
#include "skid_plugin.h"

static SkidLibraryDecl library_declaration;

SKID_EXPORT const SkidLibraryDecl *skid_plugin_entry(void) {
    library_declaration.abi_version = SKID_ABI_VERSION;
    library_declaration.layout_fingerprint = SKID_LAYOUT_FINGERPRINT;
    return &library_declaration;
}

int strict_header_entry_matches_its_type(void) {
    SkidEntryFn entry = skid_plugin_entry;
    return entry()->abi_version == SKID_ABI_VERSION && SkidStatus_BUFFER_TOO_SMALL != SkidStatus_OK;
}
