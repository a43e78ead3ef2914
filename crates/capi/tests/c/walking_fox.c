/* A host written in C (no Rust in it), as an engine uses furbake through furbake.h: it checks
 * the library's version, reads a fur pack into memory and opens it, reads the views it would
 * upload, then runs two worlds side by side — the Fox walking on its own clip, and a Fox posed
 * by this program from the clip sampler, frame by frame — and checks what a renderer would read.
 * It also opens a grass pack from its file and reads its blade field and wind forces.
 *
 * Usage: walking_fox FOX.fbk GRASS.fbk. Exit 0 and a summary on stdout when every check holds;
 * otherwise exit 1 with the failing check on stderr. Built by the crate's tests with -Wall
 * -Wextra -Wpedantic -Werror and the address and undefined-behaviour sanitizers. */

#include "furbake.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;

#define CHECK(cond, ...)                                                                             \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "walking_fox.c:%d: check failed: %s: ", __LINE__, #cond);              \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fprintf(stderr, "\n");                                                                 \
            failures++;                                                                            \
        }                                                                                          \
    } while (0)

/* Calls that must succeed: on failure, print the library's message and stop. */
#define MUST(call)                                                                                 \
    do {                                                                                           \
        FurbakeResult r_ = (call);                                                                 \
        if (r_ != FURBAKE_RESULT_OK) {                                                             \
            fprintf(stderr, "walking_fox.c:%d: %s failed (%d): %s\n", __LINE__, #call, (int)r_,    \
                    furbake_last_error());                                                         \
            exit(1);                                                                               \
        }                                                                                          \
    } while (0)

static unsigned char *read_file(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        exit(1);
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *bytes = malloc((size_t)n);
    if (!bytes || fread(bytes, 1, (size_t)n, f) != (size_t)n) {
        fprintf(stderr, "%s: cannot read\n", path);
        exit(1);
    }
    fclose(f);
    *size = (size_t)n;
    return bytes;
}

static const char SETTINGS[] = "time_step_s = 0.01\n"
                               "[effects.gravity]\n"
                               "[effects.wind]\n"
                               "velocity_m_per_s = [1.5, 0.0, 0.5]\n"
                               "gust_amplitude = 0.3\n"
                               "[effects.wrong_side_guard]\n";

static FurbakeWorld *make_world(void) {
    FurbakeWorldDesc desc = {.size = sizeof desc};
    desc.settings_toml = SETTINGS;
    desc.settings_name = "walking_fox.c settings";
    FurbakeWorld *world = NULL;
    MUST(furbake_world_create(&desc, &world));
    return world;
}

static void add_fox(FurbakeWorld *world, const FurbakePack *pack, const char *name, float speed) {
    FurbakeEntryDesc entry = {.size = sizeof entry};
    entry.name = name;
    entry.animation = FURBAKE_ANIMATION_CLIP;
    entry.clip = "Walk";
    entry.speed = speed;
    entry.looping = 1;
    entry.scale = 0.01f; /* the Fox is modelled in centimetres */
    uint32_t index = 99;
    MUST(furbake_world_add_pack(world, pack, &entry, &index));
    CHECK(index == 0, "the first entry has index 0, got %u", index);
}

static FurbakeFurFrame fur_frame(FurbakeWorld *world) {
    FurbakeFurFrame frame = {.size = sizeof frame};
    MUST(furbake_world_fur_frame(world, 0, &frame));
    return frame;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s FOX.fbk GRASS.fbk\n", argv[0]);
        return 2;
    }
    if (furbake_check_version(FURBAKE_ABI_VERSION) != FURBAKE_RESULT_OK) {
        fprintf(stderr, "%s\n", furbake_last_error());
        return 1;
    }

    /* The Fox, read into memory as an engine's asset system would, then freed. */
    size_t size = 0;
    unsigned char *bytes = read_file(argv[1], &size);
    FurbakePack *fox = NULL;
    MUST(furbake_pack_open_memory(bytes, size, "assets/fox.fbk", &fox));
    free(bytes);

    FurbakePackInfo info = {.size = sizeof info};
    MUST(furbake_pack_info(fox, &info));
    CHECK(info.contents & FURBAKE_HAS_SHELL_ATLAS, "the Fox has fur");
    CHECK(info.contents & FURBAKE_HAS_SKELETON, "the Fox has a skeleton");

    FurbakeSkinMeshView mesh = {.size = sizeof mesh};
    MUST(furbake_pack_skin_mesh(fox, &mesh));
    CHECK(mesh.vertex_count == info.vertex_count, "%u vs %u", mesh.vertex_count, info.vertex_count);
    uint32_t furry = 0;
    for (uint32_t t = 0; t < mesh.triangle_count; t++) {
        for (int c = 0; c < 3; c++) {
            CHECK(mesh.triangles[3 * t + (uint32_t)c] < mesh.vertex_count, "triangle %u", t);
        }
        furry += mesh.fur_mask[t];
    }
    for (uint32_t v = 0; v < mesh.vertex_count; v++) {
        const float *n = &mesh.normals[3 * v];
        float len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        CHECK(fabsf(len - 1.0f) < 1e-3f, "normal %u has length %f", v, (double)len);
    }

    FurbakeShellAtlasView atlas = {.size = sizeof atlas};
    MUST(furbake_pack_shell_atlas(fox, &atlas));
    size_t texels = (size_t)atlas.layers * atlas.resolution * atlas.resolution;
    size_t lit = 0;
    for (size_t i = 0; i < texels; i++) {
        lit += atlas.alpha[i] > 0;
    }
    CHECK(lit > 0 && lit < texels, "the atlas has strands and gaps (%zu of %zu)", lit, texels);

    FurbakeSkeletonView skeleton = {.size = sizeof skeleton};
    MUST(furbake_pack_skeleton(fox, &skeleton));
    CHECK(skeleton.nodes != NULL, "joints carry their glTF nodes");
    uint32_t joint_count = skeleton.joint_count;
    const char *root_name = NULL;
    MUST(furbake_pack_joint_name(fox, 0, &root_name));
    char root[64]; /* the name lives as long as the pack: copied before it is released */
    snprintf(root, sizeof root, "%s", root_name);

    /* A view of data the pack lacks: a typed answer and a message naming the pack. */
    FurbakeBladeFieldView none = {.size = sizeof none};
    CHECK(furbake_pack_blade_field(fox, &none) == FURBAKE_RESULT_MISSING, "a fur pack has no blades");
    CHECK(strstr(furbake_last_error(), "assets/fox.fbk") != NULL, "message: %s", furbake_last_error());

    /* Two worlds: the Fox walking on its clip, and a puppet Fox this program poses. */
    FurbakeWorld *walker = make_world();
    FurbakeWorld *puppet = make_world();
    add_fox(walker, fox, "walker", 1.0f);
    add_fox(puppet, fox, "puppet", 0.0f);
    FurbakeAnimator *sampler = NULL;
    MUST(furbake_animator_create(fox, "Walk", &sampler));
    furbake_pack_release(fox); /* the worlds and the sampler keep what they need */

    const int steps = 60;
    float worst_sampled = 0.0f, worst_length = 0.0f;
    int identical = 1;
    uint32_t count = 0;
    for (int k = 1; k <= steps; k++) {
        MUST(furbake_world_step(walker));
        /* The puppet's pose comes from the sampler at this frame's clip time. */
        FurbakeSkinPose pose = {.size = sizeof pose};
        MUST(furbake_animator_pose(sampler, k * 0.01, &pose));
        FurbakeSkinPose walked = {.size = sizeof walked};
        MUST(furbake_world_skin_pose(walker, 0, &walked));
        CHECK(pose.joint_count == walked.joint_count, "joints %u vs %u", pose.joint_count, walked.joint_count);
        for (uint32_t i = 0; i < 16 * pose.joint_count; i++) {
            float d = fabsf(pose.joint_matrices[i] - walked.joint_matrices[i]);
            worst_sampled = d > worst_sampled ? d : worst_sampled;
        }
        /* Handing the walker's own matrices to the puppet reproduces the walker bit for bit. */
        MUST(furbake_world_set_joint_matrices(puppet, 0, walked.joint_matrices, walked.joint_count, NULL, 0));
        MUST(furbake_world_step(puppet));
        FurbakeFurFrame a = fur_frame(walker), b = fur_frame(puppet);
        count = a.count;
        CHECK(a.simulated && a.count == b.count && a.count > 0, "fur frames of %u and %u", a.count, b.count);
        if (memcmp(a.scale_vectors, b.scale_vectors, 3 * sizeof(float) * a.count) != 0) {
            identical = 0;
        }
        for (uint32_t i = 0; i < a.count; i++) {
            const float *s = &a.scale_vectors[3 * i];
            float d = fabsf(sqrtf(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) - 1.0f);
            worst_length = d > worst_length ? d : worst_length;
        }
    }
    CHECK(identical, "the puppet's fur is the walker's");
    CHECK(worst_sampled < 1e-3f, "the sampled Walk is %g off the world's", (double)worst_sampled);
    CHECK(worst_length < 1e-4f, "scale vectors are unit vectors (worst %g)", (double)worst_length);

    /* Misuse: refused with a code, and nothing changes. */
    CHECK(furbake_world_set_joint_matrices(puppet, 0, NULL, 3, NULL, 0) == FURBAKE_RESULT_INVALID_ARGUMENT,
          "null matrices");
    FurbakeEntryDesc late = {.size = sizeof late};
    late.name = "late";
    late.scale = 1.0f;
    FurbakePack *again = NULL;
    MUST(furbake_pack_open_file(argv[1], &again));
    CHECK(furbake_world_add_pack(walker, again, &late, NULL) == FURBAKE_RESULT_STATE, "added after a step");
    furbake_pack_release(again);
    FurbakeWorldInfo winfo = {.size = sizeof winfo};
    MUST(furbake_world_info(walker, &winfo));
    CHECK(winfo.steps == (uint64_t)steps && fabs(winfo.time_s - steps * 0.01) < 1e-6, "clock %llu %f",
          (unsigned long long)winfo.steps, winfo.time_s);

    furbake_animator_release(sampler);
    furbake_world_release(walker);
    furbake_world_release(puppet);

    /* Grass: the blade field to upload, and the wind's forces per cluster corner. */
    FurbakePack *grass = NULL;
    MUST(furbake_pack_open_file(argv[2], &grass));
    FurbakeBladeFieldView field = {.size = sizeof field};
    MUST(furbake_pack_blade_field(grass, &field));
    FurbakeKeyframeTableView table = {.size = sizeof table};
    MUST(furbake_pack_keyframe_table(grass, &table));
    FurbakeWorldDesc gdesc = {.size = sizeof gdesc};
    gdesc.settings_toml = "[effects.wind]\nvelocity_m_per_s = [4.0, 0.0, 0.0]\n";
    FurbakeWorld *meadow = NULL;
    MUST(furbake_world_create(&gdesc, &meadow));
    FurbakeEntryDesc patch = {.size = sizeof patch};
    patch.name = "patch";
    patch.scale = 1.0f;
    MUST(furbake_world_add_pack(meadow, grass, &patch, NULL));
    furbake_pack_release(grass);
    for (int k = 0; k < 10; k++) {
        MUST(furbake_world_step(meadow));
    }
    FurbakeGrassFrame gf = {.size = sizeof gf};
    MUST(furbake_world_grass_frame(meadow, 0, &gf));
    CHECK(gf.corner_count == (field.grid_cells_x + 1) * (field.grid_cells_z + 1), "%u corners", gf.corner_count);
    float push = 0.0f;
    for (uint32_t i = 0; i < gf.corner_count; i++) {
        push += gf.corner_forces[2 * i];
    }
    CHECK(push > 0.0f, "the wind pushes the grass along +x (%g)", (double)push);
    furbake_world_release(meadow);

    if (failures) {
        fprintf(stderr, "%d checks failed\n", failures);
        return 1;
    }
    printf("furbake %s (ABI %u): Fox %u vertices, %u triangles (%u furry), %u joints (root \"%s\"), atlas %ux%ux%u\n",
           furbake_version(), furbake_abi_version(), mesh.vertex_count, mesh.triangle_count, furry,
           joint_count, root, atlas.resolution, atlas.resolution, atlas.layers);
    printf("%d steps: %u scale vectors, puppet identical to walker, sampler within %.2g, unit within %.2g\n", steps,
           count, (double)worst_sampled, (double)worst_length);
    printf("grass: %u blades, %u keyframe segments, wind force sum %.3g\n", field.blade_count, table.segments,
           (double)push);
    return 0;
}
