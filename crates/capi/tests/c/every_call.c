/* The calls of furbake.h that walking_fox.c and gl_fur.c leave out, each checked from C for what
 * it answers, not only that it answers: the fin atlas and fin edges, skin weights and morph
 * targets, clips, a world opened from a scene file with its packs found by name, a pack moved by
 * its model matrix, a held pose handed back to the clip player, and the effects, wind and gravity
 * changed between steps.
 *
 * Usage: every_call FOX.fbk STRIP.fbk PLANE.fbk SCENE.toml, where PLANE is a pack with fin edges and the scene holds the Fox as "fox" walking
 * its "Walk" clip and a grass pack as "grass", and declares [effects.gravity] and [effects.wind].
 * Exit 0 and one line per call group on stdout when every check holds; otherwise exit 1 with the
 * failing checks on stderr. Built by the crate's tests with warnings as errors and the address and
 * undefined-behaviour sanitizers. */

#include "furbake.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;

#define CHECK(cond, ...)                                                                             \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fprintf(stderr, "every_call.c:%d: check failed: %s: ", __LINE__, #cond);               \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fprintf(stderr, "\n");                                                                 \
            failures++;                                                                            \
        }                                                                                          \
    } while (0)

#define MUST(call)                                                                                 \
    do {                                                                                           \
        FurbakeResult r_ = (call);                                                                 \
        if (r_ != FURBAKE_RESULT_OK) {                                                             \
            fprintf(stderr, "every_call.c:%d: %s failed (%d): %s\n", __LINE__, #call, (int)r_,     \
                    furbake_last_error());                                                         \
            exit(1);                                                                               \
        }                                                                                          \
    } while (0)

/* The fin atlas and skin weights of the Fox, the fin edges of the plane, the morph targets of the
 * strip. */
static void pack_sections(const FurbakePack *fox, const FurbakePack *strip, const FurbakePack *plane) {
    FurbakePackInfo info = {.size = sizeof info};
    MUST(furbake_pack_info(fox, &info));
    FurbakeSkinMeshView mesh = {.size = sizeof mesh};
    MUST(furbake_pack_skin_mesh(fox, &mesh));
    FurbakeSkinMeshView plane_mesh = {.size = sizeof plane_mesh};
    MUST(furbake_pack_skin_mesh(plane, &plane_mesh));

    FurbakeFinAtlasView fins = {.size = sizeof fins};
    MUST(furbake_pack_fin_atlas(fox, &fins));
    size_t texels = (size_t)fins.width * fins.height, strands = 0;
    for (size_t i = 0; i < texels; i++) {
        strands += fins.alpha[i] > 0;
    }
    CHECK(fins.width > 0 && fins.height > 0 && fins.slices > 0, "fin atlas %ux%u, %u slices", fins.width,
          fins.height, fins.slices);
    CHECK(strands > 0 && strands < texels, "the fin atlas has hair and gaps (%zu of %zu)", strands, texels);

    FurbakeFinEdgesView edges = {.size = sizeof edges};
    MUST(furbake_pack_fin_edges(plane, &edges));
    CHECK(edges.edge_count > 0, "the plane has fin edges round its bare centre");
    for (uint32_t e = 0; e < edges.edge_count; e++) {
        uint32_t a = edges.vertices[2 * e], b = edges.vertices[2 * e + 1], t = edges.triangles[e];
        CHECK(a < plane_mesh.vertex_count && b < plane_mesh.vertex_count && a != b, "edge %u: %u-%u", e, a, b);
        CHECK(t < plane_mesh.triangle_count, "edge %u grows from triangle %u", e, t);
        /* Both ends are corners of the furry triangle the fin grows from. */
        int ends = 0;
        for (int c = 0; c < 3 && t < plane_mesh.triangle_count; c++) {
            uint32_t v = plane_mesh.triangles[3 * t + (uint32_t)c];
            ends += (v == a) + (v == b);
        }
        CHECK(ends == 2, "edge %u is an edge of triangle %u", e, t);
        CHECK(t >= plane_mesh.triangle_count || plane_mesh.fur_mask[t], "edge %u grows from a furry triangle", e);
    }

    FurbakeSkinWeightsView weights = {.size = sizeof weights};
    MUST(furbake_pack_skin_weights(fox, &weights));
    CHECK(weights.vertex_count == mesh.vertex_count, "%u weighted vertices of %u", weights.vertex_count,
          mesh.vertex_count);
    CHECK(weights.influences_per_vertex == 4 || weights.influences_per_vertex == 8, "%u influences",
          weights.influences_per_vertex);
    float worst = 0.0f;
    for (uint32_t v = 0; v < weights.vertex_count; v++) {
        float sum = 0.0f;
        for (uint32_t k = 0; k < weights.influences_per_vertex; k++) {
            uint32_t slot = v * weights.influences_per_vertex + k;
            sum += weights.weights[slot];
            CHECK(weights.weights[slot] == 0.0f || weights.binds[slot] < info.joint_count, "vertex %u bind %u", v,
                  weights.binds[slot]);
        }
        worst = fmaxf(worst, fabsf(sum - 1.0f));
    }
    CHECK(worst < 1e-3f, "every vertex's weights sum to 1 (worst off by %g)", (double)worst);

    FurbakeMorphTargetsView morph = {.size = sizeof morph};
    CHECK(furbake_pack_morph_targets(fox, &morph) == FURBAKE_RESULT_MISSING, "the Fox has no morph targets");
    MUST(furbake_pack_morph_targets(strip, &morph));
    FurbakePackInfo strip_info = {.size = sizeof strip_info};
    MUST(furbake_pack_info(strip, &strip_info));
    CHECK(morph.target_count == strip_info.morph_target_count && morph.target_count > 0, "%u targets",
          morph.target_count);
    CHECK(morph.vertex_count == strip_info.vertex_count, "%u morphed vertices", morph.vertex_count);
    float lift = 0.0f;
    for (uint32_t i = 0; i < 3 * morph.vertex_count * morph.target_count; i++) {
        lift = fmaxf(lift, fabsf(morph.position_deltas[i]));
    }
    CHECK(lift > 0.0f, "the target moves the strip");

    printf("sections: %ux%u fin atlas (%u slices), %u fin edges, %u influences per vertex, %u morph target(s)\n",
           fins.width, fins.height, fins.slices, edges.edge_count, weights.influences_per_vertex,
           morph.target_count);
}

/* The clips: names, lengths, and a refusal past the last. */
static void clips(const FurbakePack *fox) {
    FurbakePackInfo info = {.size = sizeof info};
    MUST(furbake_pack_info(fox, &info));
    CHECK(info.clip_count >= 1, "the Fox has clips");
    int walk = 0;
    for (uint32_t i = 0; i < info.clip_count; i++) {
        FurbakeClipInfo clip = {.size = sizeof clip};
        MUST(furbake_pack_clip(fox, i, &clip));
        CHECK(clip.name != NULL && clip.name[0] != '\0', "clip %u has a name", i);
        CHECK(clip.duration_s > 0.0f && isfinite(clip.duration_s), "clip %u lasts %g s", i, (double)clip.duration_s);
        walk |= strcmp(clip.name, "Walk") == 0;
    }
    CHECK(walk, "one clip is Walk");
    FurbakeClipInfo past = {.size = sizeof past};
    CHECK(furbake_pack_clip(fox, info.clip_count, &past) == FURBAKE_RESULT_INVALID_ARGUMENT, "past the last clip");
    printf("clips: %u, Walk among them\n", info.clip_count);
}

static float *joints_of(FurbakeWorld *world, uint32_t pack, uint32_t *count) {
    FurbakeSkinPose pose = {.size = sizeof pose};
    MUST(furbake_world_skin_pose(world, pack, &pose));
    float *copy = malloc(16 * sizeof(float) * pose.joint_count);
    if (!copy) {
        exit(1);
    }
    memcpy(copy, pose.joint_matrices, 16 * sizeof(float) * pose.joint_count);
    *count = pose.joint_count;
    return copy;
}

static double grass_push(FurbakeWorld *world, uint32_t pack) {
    FurbakeGrassFrame frame = {.size = sizeof frame};
    MUST(furbake_world_grass_frame(world, pack, &frame));
    double push = 0.0;
    for (uint32_t i = 0; i < frame.corner_count; i++) {
        push += frame.corner_forces[2 * i];
    }
    return push;
}

/* What drawing a pack takes (`furbake-draw`): fin quads, atlas levels, the Fur block of a look,
 * the shell level of detail, and their refusals. */
static void draw_data(const FurbakePack *fox, const FurbakePack *plane) {
    FurbakeFinEdgesView edges = {.size = sizeof edges};
    MUST(furbake_pack_fin_edges(plane, &edges));
    FurbakeArrayView quads = {.size = sizeof quads};
    MUST(furbake_pack_fin_quads(plane, &quads));
    CHECK(quads.count == 6 * edges.edge_count && quads.stride == 80, "%u fin corners of 80 bytes for %u edges",
          quads.count, edges.edge_count);
    FurbakeArrayView silhouette = {.size = sizeof silhouette};
    MUST(furbake_pack_silhouette_edges(fox, &silhouette));
    CHECK(silhouette.count > 0 && silhouette.stride == 32, "%u interior edges", silhouette.count);

    FurbakeShellAtlasView atlas = {.size = sizeof atlas};
    MUST(furbake_pack_shell_atlas(fox, &atlas));
    FurbakeAtlasLevelView level = {.size = sizeof level};
    MUST(furbake_pack_atlas_level(fox, FURBAKE_ATLAS_SHELL, 0, &level));
    CHECK(level.width == atlas.resolution && level.layers == atlas.layers &&
              memcmp(level.texels, atlas.alpha, (size_t)atlas.layers * atlas.resolution * atlas.resolution) == 0,
          "level 0 is the atlas");
    uint32_t count = level.level_count;
    MUST(furbake_pack_atlas_level(fox, FURBAKE_ATLAS_SHELL, count - 1, &level));
    CHECK(level.width == 1 && level.height == 1 && count > 1, "the chain ends at 1x1 (%u levels)", count);
    CHECK(furbake_pack_atlas_level(fox, FURBAKE_ATLAS_SHELL, count, &level) == FURBAKE_RESULT_INVALID_ARGUMENT,
          "past the chain");
    CHECK(furbake_pack_atlas_level(fox, 7, 0, &level) == FURBAKE_RESULT_INVALID_ARGUMENT, "an unknown atlas");

    FurbakeFurLook look = {.size = sizeof look};
    MUST(furbake_fur_look_default(&look));
    unsigned char block[128], small[112];
    MUST(furbake_pack_fur_block(fox, &look, atlas.layers, block, sizeof block));
    float length = 0.0f;
    memcpy(&length, &block[16], sizeof length); /* Fur.fur_length_m */
    CHECK(length == atlas.fur_length_m, "the block carries the fur length (%g)", (double)length);
    CHECK(furbake_pack_fur_block(fox, &look, atlas.layers, small, sizeof small) == FURBAKE_RESULT_INVALID_ARGUMENT,
          "a block of the wrong size");
    /* The samplers' anisotropy rides in Fur.stacking.y (bytes 116..120): 16 by default, also for
     * 0 and for a host built before the field (a smaller size: the library reads no further). */
    float anisotropy = 0.0f;
    memcpy(&anisotropy, &block[116], sizeof anisotropy);
    CHECK(look.anisotropy == 16.0f && anisotropy == 16.0f, "the default anisotropy (%g)", (double)anisotropy);
    FurbakeFurLook older = look;
    older.size = (uint32_t)offsetof(FurbakeFurLook, anisotropy);
    older.anisotropy = 99.0f;
    MUST(furbake_pack_fur_block(fox, &older, atlas.layers, block, sizeof block));
    memcpy(&anisotropy, &block[116], sizeof anisotropy);
    CHECK(anisotropy == 16.0f, "a look from before the field draws the default (%g)", (double)anisotropy);
    look.anisotropy = 4.0f;
    MUST(furbake_pack_fur_block(fox, &look, atlas.layers, block, sizeof block));
    memcpy(&anisotropy, &block[116], sizeof anisotropy);
    CHECK(anisotropy == 4.0f, "the look's anisotropy (%g)", (double)anisotropy);
    look.anisotropy = 17.0f;
    CHECK(furbake_pack_fur_block(fox, &look, atlas.layers, block, sizeof block) == FURBAKE_RESULT_INVALID_ARGUMENT &&
              strstr(furbake_last_error(), "anisotropy") != NULL,
          "an anisotropy out of range, named: %s", furbake_last_error());
    look.anisotropy = 0.0f;
    look.alpha_threshold = 1.5f;
    CHECK(furbake_pack_fur_block(fox, &look, atlas.layers, block, sizeof block) == FURBAKE_RESULT_INVALID_ARGUMENT &&
              strstr(furbake_last_error(), "alpha_threshold") != NULL,
          "an alpha threshold out of range, named: %s", furbake_last_error());

    /* The level of detail: near, every layer; far, fewer (one layer per pixel, down to one). */
    FurbakeWorldDesc desc = {.size = sizeof desc};
    FurbakeWorld *world = NULL;
    MUST(furbake_world_create(&desc, &world));
    FurbakeEntryDesc entry = {.size = sizeof entry, .name = "fox", .scale = 0.01f};
    MUST(furbake_world_add_pack(world, fox, &entry, NULL));
    MUST(furbake_world_step(world));
    FurbakeShellLod lod = {.size = sizeof lod, .layers_per_px = 1.0f, .min_layers = 1};
    FurbakeShellLevel near = {.size = sizeof near}, far = {.size = sizeof far};
    /* A camera at (0, 0.4, d) looking down -z: perspective (fov 40°, aspect 4:3, depth 0–1 over
     * 0.05–100 m) × a translation by (0, -0.4, -d), column-major. */
    float f = 1.0f / tanf(0.5f * 0.6981317f), zf = 100.0f / (0.05f - 100.0f);
    for (int k = 0; k < 2; k++) {
        float distance = k == 0 ? 1.5f : 60.0f;
        FurbakeCamera camera = {.size = sizeof camera, .eye = {0.0f, 0.4f, distance}, .viewport = {640.0f, 480.0f}};
        float m[16] = {f / (4.0f / 3.0f), 0, 0, 0, 0, f, 0, 0, 0, 0, zf, -1, 0, -0.4f * f, zf * (0.05f - distance), distance};
        memcpy(camera.view_proj, m, sizeof m);
        MUST(furbake_world_shell_level(world, 0, &camera, &lod, atlas.layers, k == 0 ? &near : &far));
    }
    CHECK(near.layers == atlas.layers && far.layers < near.layers, "near %u layers, far %u", near.layers, far.layers);
    lod.layers_per_px = -1.0f;
    CHECK(furbake_world_shell_level(world, 0, &(FurbakeCamera){.size = sizeof(FurbakeCamera)}, &lod, 4, &near) ==
              FURBAKE_RESULT_INVALID_ARGUMENT,
          "a negative slope");
    furbake_world_release(world);
    printf("draw: %u fin corners, %u interior edges, %u atlas levels, %u of %u layers far away\n", quads.count,
           silhouette.count, count, far.layers, atlas.layers);
}

/* A scene file: packs by name, a model matrix, a held pose handed back, effects, wind. */
static void scene(const char *path) {
    FurbakeWorld *walker = NULL, *held = NULL;
    MUST(furbake_world_open_scene(path, 0, &walker));
    MUST(furbake_world_open_scene(path, 0, &held));
    uint32_t fox = 99, grass = 99, none = 99;
    MUST(furbake_world_pack_index(walker, "fox", &fox));
    MUST(furbake_world_pack_index(walker, "grass", &grass));
    CHECK(fox != grass && fox < 2 && grass < 2, "fox %u, grass %u", fox, grass);
    CHECK(furbake_world_pack_index(walker, "wolf", &none) == FURBAKE_RESULT_INVALID_ARGUMENT && none == 99,
          "an unknown name is refused and writes nothing");
    CHECK(strstr(furbake_last_error(), "wolf") != NULL, "the message names it: %s", furbake_last_error());

    /* The model matrix: set, read back; a sheared one is refused and changes nothing. */
    float model[16] = {0.02f, 0, 0, 0, 0, 0.02f, 0, 0, 0, 0, 0.02f, 0, 1.5f, 0, -2.0f, 1};
    MUST(furbake_world_set_model_matrix(walker, fox, model));
    MUST(furbake_world_set_model_matrix(held, fox, model));
    float sheared[16];
    memcpy(sheared, model, sizeof model);
    sheared[4] = 0.01f;
    CHECK(furbake_world_set_model_matrix(walker, fox, sheared) == FURBAKE_RESULT_INVALID_ARGUMENT, "shear refused");
    /* A placement holds from the end of the next step. */
    MUST(furbake_world_step(walker));
    MUST(furbake_world_step(held));
    float back[16] = {0};
    MUST(furbake_world_model_matrix(walker, fox, back));
    CHECK(memcmp(back, model, sizeof model) == 0, "the model matrix reads back, the sheared one left out");

    /* Hold the second Fox in its first pose for 5 steps, then hand it back to the clip player:
     * held, it stays put while the walker walks; resumed, it is the walker again (the clip's time
     * went on meanwhile). */
    uint32_t joints = 0;
    float *first = joints_of(walker, fox, &joints);
    for (int k = 0; k < 5; k++) {
        MUST(furbake_world_set_joint_matrices(held, fox, first, joints, NULL, 0));
        MUST(furbake_world_step(walker));
        MUST(furbake_world_step(held));
    }
    uint32_t n = 0;
    float *walked = joints_of(walker, fox, &n), *posed = joints_of(held, fox, &n);
    CHECK(memcmp(posed, first, 16 * sizeof(float) * joints) == 0, "held, the pose stays");
    CHECK(memcmp(walked, first, 16 * sizeof(float) * joints) != 0, "the walker walked on");
    free(walked);
    free(posed);
    MUST(furbake_world_resume_clips(held, fox));
    CHECK(furbake_world_resume_clips(held, grass) == FURBAKE_RESULT_INVALID_ARGUMENT, "grass has no clips");
    MUST(furbake_world_step(walker));
    MUST(furbake_world_step(held));
    walked = joints_of(walker, fox, &n);
    posed = joints_of(held, fox, &n);
    CHECK(memcmp(posed, walked, 16 * sizeof(float) * joints) == 0, "resumed, the clip poses it as the walker");
    free(first);
    free(walked);
    free(posed);

    /* Effects: the scene's wind pushes along +x; the same wind set through the typed setter
     * reverses it, and an [effects] text calming it stops it. An effect the scene did not declare
     * is refused. */
    double scene_wind = grass_push(walker, grass);
    FurbakeWind wind = {.size = sizeof wind, .velocity_m_per_s = {-3.0f, 0.0f, 0.0f}};
    MUST(furbake_world_set_wind(walker, &wind));
    for (int k = 0; k < 10; k++) {
        MUST(furbake_world_step(walker));
    }
    double reversed = grass_push(walker, grass);
    MUST(furbake_world_set_effects(walker, "[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [0.0, 0.0, 0.0]\n"));
    for (int k = 0; k < 10; k++) {
        MUST(furbake_world_step(walker));
    }
    double calm = grass_push(walker, grass);
    CHECK(scene_wind > 0.0 && reversed < 0.0, "wind +x pushes %g, -x pushes %g", scene_wind, reversed);
    CHECK(fabs(calm) < 1e-6 * fabs(scene_wind), "calmed, the wind pushes %g", calm);
    CHECK(furbake_world_set_effects(walker, "[effects.object_motion]\n") != FURBAKE_RESULT_OK,
          "an effect the world did not declare");
    printf("scene: fox %u, grass %u; held pose kept and resumed; wind %+.3g, reversed %+.3g, calm %+.3g\n", fox, grass,
           scene_wind, reversed, calm);
    furbake_world_release(walker);
    furbake_world_release(held);
}

/* Mean y of a standing Fox's hair directions after 40 steps under `gravity`. */
static float hair_rise(const FurbakePack *fox, const float gravity[3]) {
    FurbakeWorldDesc desc = {.size = sizeof desc, .time_step_s = 0.01f, .settings_toml = "[effects.gravity]\n"};
    FurbakeWorld *world = NULL;
    MUST(furbake_world_create(&desc, &world));
    FurbakeEntryDesc entry = {.size = sizeof entry, .name = "fox", .scale = 0.01f};
    MUST(furbake_world_add_pack(world, fox, &entry, NULL));
    MUST(furbake_world_set_gravity(world, gravity));
    for (int k = 0; k < 40; k++) {
        MUST(furbake_world_step(world));
    }
    FurbakeFurFrame frame = {.size = sizeof frame};
    MUST(furbake_world_fur_frame(world, 0, &frame));
    double y = 0.0;
    for (uint32_t i = 0; i < frame.count; i++) {
        y += frame.scale_vectors[3 * i + 1];
    }
    furbake_world_release(world);
    return (float)(y / frame.count);
}

static void gravity(const FurbakePack *fox) {
    const float down[3] = {0.0f, -9.81f, 0.0f}, up[3] = {0.0f, 9.81f, 0.0f}, bad[3] = {0.0f, NAN, 0.0f};
    float fall = hair_rise(fox, down), rise = hair_rise(fox, up);
    CHECK(rise > fall + 0.01f, "hair hangs with gravity (%g) and rises against it (%g)", (double)fall, (double)rise);
    FurbakeWorld *world = NULL;
    FurbakeWorldDesc desc = {.size = sizeof desc, .settings_toml = "[effects.wind]\nvelocity_m_per_s = [0.0, 0.0, 0.0]\n"};
    MUST(furbake_world_create(&desc, &world));
    FurbakeEntryDesc entry = {.size = sizeof entry, .name = "fox", .scale = 0.01f};
    MUST(furbake_world_add_pack(world, fox, &entry, NULL));
    CHECK(furbake_world_set_gravity(world, down) != FURBAKE_RESULT_OK, "gravity the world did not declare");
    CHECK(furbake_world_set_gravity(world, bad) != FURBAKE_RESULT_OK, "NaN gravity");
    furbake_world_release(world);
    printf("gravity: mean hair y %.3f falling, %.3f rising\n", (double)fall, (double)rise);
}

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: %s FOX.fbk STRIP.fbk PLANE.fbk SCENE.toml\n", argv[0]);
        return 2;
    }
    if (furbake_check_version(FURBAKE_ABI_VERSION) != FURBAKE_RESULT_OK) {
        fprintf(stderr, "%s\n", furbake_last_error());
        return 1;
    }
    FurbakePack *fox = NULL, *strip = NULL, *plane = NULL;
    MUST(furbake_pack_open_file(argv[1], &fox));
    MUST(furbake_pack_open_file(argv[2], &strip));
    MUST(furbake_pack_open_file(argv[3], &plane));
    pack_sections(fox, strip, plane);
    clips(fox);
    draw_data(fox, plane);
    scene(argv[4]);
    gravity(fox);
    furbake_pack_release(fox);
    furbake_pack_release(strip);
    furbake_pack_release(plane);
    if (failures) {
        fprintf(stderr, "%d checks failed\n", failures);
        return 1;
    }
    printf("every call answered as documented\n");
    return 0;
}
