/* Test fixture in C against the generated header: a fine registration plugin, `liar`, that misbehaves
 * the way its config says, so the host's checks of what a plugin returns can be seen to hold:
 *   behaviour = "long_failure"     refine claims a failure text longer than the host's buffer;
 *   behaviour = "scaled"           refine returns a matrix that is not a rigid motion;
 *   behaviour = "fails"            refine returns FAILED with a message;
 *   behaviour = "honest"           refine returns the guess, converged;
 *   behaviour = "racy"             refine returns the guess through a global scratch buffer, and waits
 *                                  (up to 100 ms) for another call to be inside at the same time, so
 *                                  instances run together read each other's guess.
 * A second plugin, `overcounting_liar`, has prepared clouds that claim a point more than they were given.
 * Compiled with -DSKID_FIXTURE_NULL_ENTRY, the function table has a null `refine`, and with
 * -DSKID_FIXTURE_WRONG_LAYOUT the declaration carries another wire-layout fingerprint, and with
 * -DSKID_FIXTURE_ENTRY_AS_DATA the entry symbol is a data object: each library must be refused at load
 * time. -DSKID_FIXTURE_SERIAL declares `liar` serial (the host must then keep
 * its racy calls apart) and -DSKID_FIXTURE_PINNED declares it pinned to its creating thread (refused). */

#define _POSIX_C_SOURCE 200809L

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "skid_plugin.h"

enum Behaviour { HONEST, LONG_FAILURE, SCALED, FAILS, RACY };

/* The racy behaviour's scratch buffer, shared by every instance: the defect the threading checks catch. */
static SkidAbiTransform SCRATCH;
/* How many racy calls are inside `refine` now. */
static atomic_int INSIDE;

typedef struct Instance {
    enum Behaviour behaviour;
} Instance;

typedef struct Prepared {
    SkidPoint *points;
    size_t count;
} Prepared;

static SkidAbiStr text(const char *value) {
    SkidAbiStr out = {(const uint8_t *)value, strlen(value)};
    return out;
}

static SkidStatus fail(SkidErrorBuf *error, SkidStatus status, const char *message) {
    if (error != NULL && error->message != NULL) {
        size_t n = strlen(message);
        if (n > error->message_capacity) n = error->message_capacity;
        memcpy(error->message, message, n);
        error->message_len = n;
    }
    return status;
}

static int contains(SkidAbiStr haystack, const char *needle) {
    size_t n = strlen(needle);
    for (size_t i = 0; i + n <= haystack.len; ++i) {
        if (memcmp(haystack.ptr + i, needle, n) == 0) return 1;
    }
    return 0;
}

static SkidStatus create(SkidAbiStr config, const SkidHostContext *context, SkidHandle *out_handle,
                         SkidErrorBuf *error) {
    (void)context;
    Instance *instance = malloc(sizeof *instance);
    if (instance == NULL) return fail(error, SkidStatus_FAILED, "out of memory");
    instance->behaviour = HONEST;
    if (contains(config, "long_failure")) instance->behaviour = LONG_FAILURE;
    if (contains(config, "scaled")) instance->behaviour = SCALED;
    if (contains(config, "\"fails\"")) instance->behaviour = FAILS;
    if (contains(config, "racy")) instance->behaviour = RACY;
    *out_handle = instance;
    return SkidStatus_OK;
}

static SkidStatus prepare(SkidHandle handle, SkidAbiCloud cloud, SkidHandle *out_prepared, SkidErrorBuf *error) {
    (void)handle;
    Prepared *prepared = malloc(sizeof *prepared);
    if (prepared == NULL) return fail(error, SkidStatus_FAILED, "out of memory");
    prepared->count = cloud.count;
    prepared->points = malloc((cloud.count + 1) * sizeof(SkidPoint));
    if (cloud.count > 0) memcpy(prepared->points, cloud.points, cloud.count * sizeof(SkidPoint));
    *out_prepared = prepared;
    return SkidStatus_OK;
}

static SkidStatus prepared_points(SkidHandle prepared, SkidAbiCloud *out_cloud, SkidErrorBuf *error) {
    (void)error;
    const Prepared *kept = prepared;
    out_cloud->points = kept->points;
    out_cloud->count = kept->count;
    return SkidStatus_OK;
}

static SkidStatus refine(SkidHandle handle, SkidHandle target, SkidHandle source, const SkidAbiTransform *guess,
                         SkidFineResult *out, SkidErrorBuf *error) {
    (void)target;
    (void)source;
    const Instance *instance = handle;
    out->target_from_source = *guess;
    out->converged = 1;
    out->iterations = 1;
    out->inlier_count = 100;
    out->inlier_ratio = 1.0;
    out->error = 0.0;
    out->failure.len = 0;
    switch (instance->behaviour) {
        case LONG_FAILURE:
            out->converged = 0;
            out->failure.len = out->failure.capacity + 100;
            break;
        case SCALED:
            out->target_from_source.matrix[0] = 2.0;
            break;
        case FAILS:
            return fail(error, SkidStatus_FAILED, "the liar gives up");
        case RACY: {
            struct timespec pause = {0, 500000};
            SCRATCH = *guess;
            atomic_fetch_add(&INSIDE, 1);
            for (int wait = 0; wait < 200 && atomic_load(&INSIDE) < 2; ++wait) nanosleep(&pause, NULL);
            out->target_from_source = SCRATCH;
            nanosleep(&pause, NULL);
            atomic_fetch_sub(&INSIDE, 1);
            break;
        }
        default:
            break;
    }
    return SkidStatus_OK;
}

static SkidStatus destroy_prepared(SkidHandle prepared, SkidErrorBuf *error) {
    (void)error;
    Prepared *kept = prepared;
    free(kept->points);
    free(kept);
    return SkidStatus_OK;
}

static SkidStatus destroy(SkidHandle handle, SkidErrorBuf *error) {
    (void)error;
    free(handle);
    return SkidStatus_OK;
}

/* A second plugin whose prepared clouds claim one point more than they were given. */
static SkidStatus prepared_points_too_many(SkidHandle prepared, SkidAbiCloud *out_cloud, SkidErrorBuf *error) {
    SkidStatus status = prepared_points(prepared, out_cloud, error);
    out_cloud->count += 1;
    return status;
}

#ifdef SKID_FIXTURE_NULL_ENTRY
static const SkidFineVTable TABLE = {create, prepare, prepared_points, NULL, destroy_prepared, destroy};
#else
static const SkidFineVTable TABLE = {create, prepare, prepared_points, refine, destroy_prepared, destroy};
#endif
static const SkidFineVTable OVERCOUNTING_TABLE = {create, prepare, prepared_points_too_many, refine,
                                                  destroy_prepared, destroy};

static SkidPluginDecl PLUGINS[2];
static SkidLibraryDecl LIBRARY;

#ifdef SKID_FIXTURE_ENTRY_AS_DATA
/* The mistake the header warns against: the entry exported as a data object pointing at the declaration
 * (compiled with -DSKID_PLUGIN_ENTRY_DECLARED, so the header's function declaration is left out). */
__attribute__((visibility("default"))) const SkidLibraryDecl *const skid_plugin_entry = &LIBRARY;
#else
SKID_EXPORT const SkidLibraryDecl *skid_plugin_entry(void) {
    PLUGINS[0].slot_kind = SkidSlotKind_FINE;
#if defined(SKID_FIXTURE_SERIAL)
    PLUGINS[0].threading = SkidThreading_SERIAL;
#elif defined(SKID_FIXTURE_PINNED)
    PLUGINS[0].threading = SkidThreading_PINNED_TO_CREATING_THREAD;
#endif
    PLUGINS[0].name = text("liar");
    PLUGINS[0].summary = text("A fine registration that lies as told (test fixture)");
    PLUGINS[0].default_config = text("behaviour = \"honest\"\n");
    PLUGINS[0].slot_table = &TABLE;
    PLUGINS[1].slot_kind = SkidSlotKind_FINE;
    PLUGINS[1].name = text("overcounting_liar");
    PLUGINS[1].summary = text("Its prepared clouds claim a point more than they were given (test fixture)");
    PLUGINS[1].default_config = text("");
    PLUGINS[1].slot_table = &OVERCOUNTING_TABLE;
    LIBRARY.abi_version = SKID_ABI_VERSION;
#ifdef SKID_FIXTURE_WRONG_LAYOUT
    LIBRARY.layout_fingerprint = SKID_LAYOUT_FINGERPRINT ^ 1u;
#else
    LIBRARY.layout_fingerprint = SKID_LAYOUT_FINGERPRINT;
#endif
    LIBRARY.framework_version = text(SKID_FRAMEWORK_VERSION);
    LIBRARY.name = text("broken-fine-fixture");
    LIBRARY.set_logger = NULL;
    LIBRARY.plugin_count = 2;
    LIBRARY.plugins = PLUGINS;
    return &LIBRARY;
}
#endif
