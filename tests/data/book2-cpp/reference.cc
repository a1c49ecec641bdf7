//==============================================================================================
// Reference driver for "Ray Tracing: The Next Week" (v3.2.3).
//
// This file replaces the book's TheNextWeek/main.cc. It renders the scene that the book's text has
// at one of the book's rendered figures, with the book's unmodified headers, camera, pixel loop,
// ray_color and write_color:
//
//     reference SCENE WIDTH SPP SEED > out.ppm
//
// SCENE is a figure number (2.01 2.02 2.03 2.07 ... 2.13 2.15 ... 2.22). srand(SEED) is called
// before the scene is built; SEED 1 is the book's own stream (the book never calls srand).
// With a fifth argument SCENE_SEED, the scene is built from srand(SCENE_SEED) and the render
// then starts afresh from srand(SEED): the same scene, other noise.
// The earth texture is read from $EARTHMAP, or from "earthmap.jpg" in the working directory.
//
// The scene functions copied from main.cc are verbatim except where a comment says otherwise.
// The functions for earlier stages of the text (figures 2.01, 2.02, 2.07-2.12, 2.16, 2.18, 2.19)
// are the text's listings at those figures. See README.md for the full list of changes.
//
// Based on the book's main.cc, originally written in 2016 by Peter Shirley <ptrshrl@gmail.com>.
// To the extent possible under law, the author(s) have dedicated all copyright and related and
// neighboring rights to this software to the public domain worldwide. This software is
// distributed without any warranty. See COPYING.txt (CC0 1.0).
//==============================================================================================

#include "rtweekend.h"

#include "box.h"
#include "bvh.h"
#include "camera.h"
#include "color.h"
#include "constant_medium.h"
#include "hittable_list.h"
#include "material.h"
#include "moving_sphere.h"
#include "sphere.h"
#include "texture.h"

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>


// Path of the earth texture (figures 2.15 and 2.22); the book hard-codes "earthmap.jpg".
static const char* earthmap_path = "earthmap.jpg";


//----------------------------------------------------------------------------------------------
// The two ray_color functions.
//----------------------------------------------------------------------------------------------

// Book 1's ray_color with the sky gradient. The text keeps this one up to and including figure
// 2.15; the `background` parameter arrives only in the "Rectangles and Lights" chapter.
color ray_color_sky(const ray& r, const hittable& world, int depth) {
    hit_record rec;

    // If we've exceeded the ray bounce limit, no more light is gathered.
    if (depth <= 0)
        return color(0,0,0);

    if (world.hit(r, 0.001, infinity, rec)) {
        ray scattered;
        color attenuation;
        if (rec.mat_ptr->scatter(r, rec, attenuation, scattered))
            return attenuation * ray_color_sky(scattered, world, depth-1);
        return color(0,0,0);
    }

    vec3 unit_direction = unit_vector(r.direction());
    auto t = 0.5*(unit_direction.y() + 1.0);
    return (1.0-t)*color(1.0, 1.0, 1.0) + t*color(0.5, 0.7, 1.0);
}


// The final main.cc's ray_color (verbatim).
color ray_color(const ray& r, const color& background, const hittable& world, int depth) {
    hit_record rec;

    // If we've exceeded the ray bounce limit, no more light is gathered.
    if (depth <= 0)
        return color(0,0,0);

    // If the ray hits nothing, return the background color.
    if (!world.hit(r, 0.001, infinity, rec))
        return background;

    ray scattered;
    color attenuation;
    color emitted = rec.mat_ptr->emitted(rec.u, rec.v, rec.p);

    if (!rec.mat_ptr->scatter(r, rec, attenuation, scattered))
        return emitted;

    return emitted + attenuation * ray_color(scattered, background, world, depth-1);
}


//----------------------------------------------------------------------------------------------
// Intermediate noise of the Perlin chapter (figures 2.07-2.12). The book's perlin.h and texture.h
// hold only the final version (figure 2.13); these are the text's earlier listings, renamed so
// that they can sit next to the book's classes.
//----------------------------------------------------------------------------------------------

// Listing [perlin] (random floats on the lattice), with the noise() of each later listing:
//   hashed_noise    - listing [perlin]            (figure 2.07)
//   trilinear_noise - listing [perlin-trilinear]  (figure 2.08)
//   smoothed_noise  - listing [perlin-smoothed]   (figures 2.09, 2.10)
class perlin_ranfloat {
    public:
        perlin_ranfloat() {
            ranfloat = new double[point_count];
            for (int i = 0; i < point_count; ++i) {
                ranfloat[i] = random_double();
            }

            perm_x = perlin_generate_perm();
            perm_y = perlin_generate_perm();
            perm_z = perlin_generate_perm();
        }

        ~perlin_ranfloat() {
            delete[] ranfloat;
            delete[] perm_x;
            delete[] perm_y;
            delete[] perm_z;
        }

        double hashed_noise(const point3& p) const {
            auto i = static_cast<int>(4*p.x()) & 255;
            auto j = static_cast<int>(4*p.y()) & 255;
            auto k = static_cast<int>(4*p.z()) & 255;

            return ranfloat[perm_x[i] ^ perm_y[j] ^ perm_z[k]];
        }

        double trilinear_noise(const point3& p) const {
            auto u = p.x() - floor(p.x());
            auto v = p.y() - floor(p.y());
            auto w = p.z() - floor(p.z());

            return lattice_interp(p, u, v, w);
        }

        double smoothed_noise(const point3& p) const {
            auto u = p.x() - floor(p.x());
            auto v = p.y() - floor(p.y());
            auto w = p.z() - floor(p.z());

            u = u*u*(3-2*u);
            v = v*v*(3-2*v);
            w = w*w*(3-2*w);

            return lattice_interp(p, u, v, w);
        }

    private:
        static const int point_count = 256;
        double* ranfloat;
        int* perm_x;
        int* perm_y;
        int* perm_z;

        // The common tail of listings [perlin-trilinear] and [perlin-smoothed].
        double lattice_interp(const point3& p, double u, double v, double w) const {
            auto i = static_cast<int>(floor(p.x()));
            auto j = static_cast<int>(floor(p.y()));
            auto k = static_cast<int>(floor(p.z()));
            double c[2][2][2];

            for (int di=0; di < 2; di++)
                for (int dj=0; dj < 2; dj++)
                    for (int dk=0; dk < 2; dk++)
                        c[di][dj][dk] = ranfloat[
                            perm_x[(i+di) & 255] ^
                            perm_y[(j+dj) & 255] ^
                            perm_z[(k+dk) & 255]
                        ];

            return trilinear_interp(c, u, v, w);
        }

        static int* perlin_generate_perm() {
            auto p = new int[point_count];

            for (int i = 0; i < perlin_ranfloat::point_count; i++)
                p[i] = i;

            permute(p, point_count);

            return p;
        }

        static void permute(int* p, int n) {
            for (int i = n-1; i > 0; i--) {
                int target = random_int(0, i);
                int tmp = p[i];
                p[i] = p[target];
                p[target] = tmp;
            }
        }

        static double trilinear_interp(double c[2][2][2], double u, double v, double w) {
            auto accum = 0.0;
            for (int i=0; i < 2; i++)
                for (int j=0; j < 2; j++)
                    for (int k=0; k < 2; k++)
                        accum += (i*u + (1-i)*(1-u))*
                                (j*v + (1-j)*(1-v))*
                                (k*w + (1-k)*(1-w))*c[i][j][k];

            return accum;
        }
};


// Figure 2.07, listing [noise-texture]: color(1,1,1) * noise.noise(p), hashed blocks.
class hashed_noise_texture : public texture {
    public:
        hashed_noise_texture() {}

        virtual color value(double u, double v, const point3& p) const override {
            return color(1,1,1) * noise.hashed_noise(p);
        }

    public:
        perlin_ranfloat noise;
};


// Figure 2.08: listing [noise-texture] over listing [perlin-trilinear].
class trilinear_noise_texture : public texture {
    public:
        trilinear_noise_texture() {}

        virtual color value(double u, double v, const point3& p) const override {
            return color(1,1,1) * noise.trilinear_noise(p);
        }

    public:
        perlin_ranfloat noise;
};


// Figures 2.09 and 2.10: listing [perlin-smoothed]; 2.09 uses noise(p) (here scale 1, and
// 1.0*p == p exactly), 2.10 listing [perlin-smoothed-2] uses noise(scale * p) with scale 4.
class smoothed_noise_texture : public texture {
    public:
        smoothed_noise_texture(double sc) : scale(sc) {}

        virtual color value(double u, double v, const point3& p) const override {
            return color(1,1,1) * noise.smoothed_noise(scale * p);
        }

    public:
        perlin_ranfloat noise;
        double scale;
};


// Figure 2.11: the book's perlin (random vectors), with the texture of the second listing
// named [perlin-smoothed-2].
class shifted_noise_texture : public texture {
    public:
        shifted_noise_texture(double sc) : scale(sc) {}

        virtual color value(double u, double v, const point3& p) const override {
            return color(1,1,1) * 0.5 * (1.0 + noise.noise(scale * p));
        }

    public:
        perlin noise;
        double scale;
};


// Figure 2.12: listing [noise-tex-2], turbulence used directly.
class turb_noise_texture : public texture {
    public:
        turb_noise_texture(double sc) : scale(sc) {}

        virtual color value(double u, double v, const point3& p) const override {
            return color(1,1,1) * noise.turb(scale * p);
        }

    public:
        perlin noise;
        double scale;
};


//----------------------------------------------------------------------------------------------
// Scenes as the text has them at earlier figures.
//----------------------------------------------------------------------------------------------

// Figures 2.01 and 2.02: listing [scene-spheres-moving] (grey ground) and listing
// [checker-example] (checkered ground). At this point of the text there is no BVH: the plain
// hittable_list is returned.
hittable_list random_scene_text(bool checkered_ground) {
    hittable_list world;

    if (checkered_ground) {
        auto checker = make_shared<checker_texture>(color(0.2, 0.3, 0.1), color(0.9, 0.9, 0.9));
        world.add(make_shared<sphere>(point3(0,-1000,0), 1000, make_shared<lambertian>(checker)));
    } else {
        auto ground_material = make_shared<lambertian>(color(0.5, 0.5, 0.5));
        world.add(make_shared<sphere>(point3(0,-1000,0), 1000, ground_material));
    }

    for (int a = -11; a < 11; a++) {
        for (int b = -11; b < 11; b++) {
            auto choose_mat = random_double();
            point3 center(a + 0.9*random_double(), 0.2, b + 0.9*random_double());

            if ((center - vec3(4, 0.2, 0)).length() > 0.9) {
                shared_ptr<material> sphere_material;

                if (choose_mat < 0.8) {
                    // diffuse
                    auto albedo = color::random() * color::random();
                    sphere_material = make_shared<lambertian>(albedo);
                    auto center2 = center + vec3(0, random_double(0,.5), 0);
                    world.add(make_shared<moving_sphere>(
                        center, center2, 0.0, 1.0, 0.2, sphere_material));
                } else if (choose_mat < 0.95) {
                    // metal
                    auto albedo = color::random(0.5, 1);
                    auto fuzz = random_double(0, 0.5);
                    sphere_material = make_shared<metal>(albedo, fuzz);
                    world.add(make_shared<sphere>(center, 0.2, sphere_material));
                } else {
                    // glass
                    sphere_material = make_shared<dielectric>(1.5);
                    world.add(make_shared<sphere>(center, 0.2, sphere_material));
                }
            }
        }
    }

    auto material1 = make_shared<dielectric>(1.5);
    world.add(make_shared<sphere>(point3(0, 1, 0), 1.0, material1));

    auto material2 = make_shared<lambertian>(color(0.4, 0.2, 0.1));
    world.add(make_shared<sphere>(point3(-4, 1, 0), 1.0, material2));

    auto material3 = make_shared<metal>(color(0.7, 0.6, 0.5), 0.0);
    world.add(make_shared<sphere>(point3(4, 1, 0), 1.0, material3));

    return world;
}


// Figures 2.07-2.12: two_perlin_spheres() with the texture of that stage (one shared texture,
// so one noise table, as in the book).
hittable_list two_perlin_spheres_with(shared_ptr<texture> pertext) {
    hittable_list objects;

    objects.add(make_shared<sphere>(point3(0,-1000,0), 1000, make_shared<lambertian>(pertext)));
    objects.add(make_shared<sphere>(point3(0, 2, 0), 2, make_shared<lambertian>(pertext)));

    return objects;
}


// Figure 2.16: listing [rect-light] (no sphere light yet).
hittable_list simple_light_text() {
    hittable_list objects;

    auto pertext = make_shared<noise_texture>(4);
    objects.add(make_shared<sphere>(point3(0,-1000,0), 1000, make_shared<lambertian>(pertext)));
    objects.add(make_shared<sphere>(point3(0,2,0), 2, make_shared<lambertian>(pertext)));

    auto difflight = make_shared<diffuse_light>(color(4,4,4));
    objects.add(make_shared<xy_rect>(3, 5, 1, 3, -2, difflight));

    return objects;
}


// Figure 2.18: listing [cornell-box-empty] (the text adds the floor before the ceiling; the final
// main.cc has the ceiling first). Figure 2.19 adds listing [add-boxes]: two unrotated blocks.
hittable_list cornell_box_text(bool with_blocks) {
    hittable_list objects;

    auto red   = make_shared<lambertian>(color(.65, .05, .05));
    auto white = make_shared<lambertian>(color(.73, .73, .73));
    auto green = make_shared<lambertian>(color(.12, .45, .15));
    auto light = make_shared<diffuse_light>(color(15, 15, 15));

    objects.add(make_shared<yz_rect>(0, 555, 0, 555, 555, green));
    objects.add(make_shared<yz_rect>(0, 555, 0, 555, 0, red));
    objects.add(make_shared<xz_rect>(213, 343, 227, 332, 554, light));
    objects.add(make_shared<xz_rect>(0, 555, 0, 555, 0, white));
    objects.add(make_shared<xz_rect>(0, 555, 0, 555, 555, white));
    objects.add(make_shared<xy_rect>(0, 555, 0, 555, 555, white));

    if (with_blocks) {
        objects.add(make_shared<box>(point3(130, 0, 65), point3(295, 165, 230), white));
        objects.add(make_shared<box>(point3(265, 0, 295), point3(430, 330, 460), white));
    }

    return objects;
}


//----------------------------------------------------------------------------------------------
// Scenes from the book's final main.cc (verbatim, except the earth texture's path).
//----------------------------------------------------------------------------------------------

hittable_list two_spheres() {
    hittable_list objects;

    auto checker = make_shared<checker_texture>(color(0.2, 0.3, 0.1), color(0.9, 0.9, 0.9));

    objects.add(make_shared<sphere>(point3(0,-10, 0), 10, make_shared<lambertian>(checker)));
    objects.add(make_shared<sphere>(point3(0, 10, 0), 10, make_shared<lambertian>(checker)));

    return objects;
}


hittable_list two_perlin_spheres() {
    hittable_list objects;

    auto pertext = make_shared<noise_texture>(4);
    objects.add(make_shared<sphere>(point3(0,-1000,0), 1000, make_shared<lambertian>(pertext)));
    objects.add(make_shared<sphere>(point3(0,2,0), 2, make_shared<lambertian>(pertext)));

    return objects;
}


hittable_list earth() {
    auto earth_texture = make_shared<image_texture>(earthmap_path);  // book: "earthmap.jpg"
    auto earth_surface = make_shared<lambertian>(earth_texture);
    auto globe = make_shared<sphere>(point3(0,0,0), 2, earth_surface);

    return hittable_list(globe);
}


hittable_list simple_light() {
    hittable_list objects;

    auto pertext = make_shared<noise_texture>(4);
    objects.add(make_shared<sphere>(point3(0,-1000,0), 1000, make_shared<lambertian>(pertext)));
    objects.add(make_shared<sphere>(point3(0,2,0), 2, make_shared<lambertian>(pertext)));

    auto difflight = make_shared<diffuse_light>(color(4,4,4));
    objects.add(make_shared<sphere>(point3(0,7,0), 2, difflight));
    objects.add(make_shared<xy_rect>(3, 5, 1, 3, -2, difflight));

    return objects;
}


hittable_list cornell_box() {
    hittable_list objects;

    auto red   = make_shared<lambertian>(color(.65, .05, .05));
    auto white = make_shared<lambertian>(color(.73, .73, .73));
    auto green = make_shared<lambertian>(color(.12, .45, .15));
    auto light = make_shared<diffuse_light>(color(15, 15, 15));

    objects.add(make_shared<yz_rect>(0, 555, 0, 555, 555, green));
    objects.add(make_shared<yz_rect>(0, 555, 0, 555, 0, red));
    objects.add(make_shared<xz_rect>(213, 343, 227, 332, 554, light));
    objects.add(make_shared<xz_rect>(0, 555, 0, 555, 555, white));
    objects.add(make_shared<xz_rect>(0, 555, 0, 555, 0, white));
    objects.add(make_shared<xy_rect>(0, 555, 0, 555, 555, white));

    shared_ptr<hittable> box1 = make_shared<box>(point3(0,0,0), point3(165,330,165), white);
    box1 = make_shared<rotate_y>(box1, 15);
    box1 = make_shared<translate>(box1, vec3(265,0,295));
    objects.add(box1);

    shared_ptr<hittable> box2 = make_shared<box>(point3(0,0,0), point3(165,165,165), white);
    box2 = make_shared<rotate_y>(box2, -18);
    box2 = make_shared<translate>(box2, vec3(130,0,65));
    objects.add(box2);

    return objects;
}


hittable_list cornell_smoke() {
    hittable_list objects;

    auto red   = make_shared<lambertian>(color(.65, .05, .05));
    auto white = make_shared<lambertian>(color(.73, .73, .73));
    auto green = make_shared<lambertian>(color(.12, .45, .15));
    auto light = make_shared<diffuse_light>(color(7, 7, 7));

    objects.add(make_shared<yz_rect>(0, 555, 0, 555, 555, green));
    objects.add(make_shared<yz_rect>(0, 555, 0, 555, 0, red));
    objects.add(make_shared<xz_rect>(113, 443, 127, 432, 554, light));
    objects.add(make_shared<xz_rect>(0, 555, 0, 555, 555, white));
    objects.add(make_shared<xz_rect>(0, 555, 0, 555, 0, white));
    objects.add(make_shared<xy_rect>(0, 555, 0, 555, 555, white));

    shared_ptr<hittable> box1 = make_shared<box>(point3(0,0,0), point3(165,330,165), white);
    box1 = make_shared<rotate_y>(box1, 15);
    box1 = make_shared<translate>(box1, vec3(265,0,295));

    shared_ptr<hittable> box2 = make_shared<box>(point3(0,0,0), point3(165,165,165), white);
    box2 = make_shared<rotate_y>(box2, -18);
    box2 = make_shared<translate>(box2, vec3(130,0,65));

    objects.add(make_shared<constant_medium>(box1, 0.01, color(0,0,0)));
    objects.add(make_shared<constant_medium>(box2, 0.01, color(1,1,1)));

    return objects;
}


hittable_list final_scene() {
    hittable_list boxes1;
    auto ground = make_shared<lambertian>(color(0.48, 0.83, 0.53));

    const int boxes_per_side = 20;
    for (int i = 0; i < boxes_per_side; i++) {
        for (int j = 0; j < boxes_per_side; j++) {
            auto w = 100.0;
            auto x0 = -1000.0 + i*w;
            auto z0 = -1000.0 + j*w;
            auto y0 = 0.0;
            auto x1 = x0 + w;
            auto y1 = random_double(1,101);
            auto z1 = z0 + w;

            boxes1.add(make_shared<box>(point3(x0,y0,z0), point3(x1,y1,z1), ground));
        }
    }

    hittable_list objects;

    objects.add(make_shared<bvh_node>(boxes1, 0, 1));

    auto light = make_shared<diffuse_light>(color(7, 7, 7));
    objects.add(make_shared<xz_rect>(123, 423, 147, 412, 554, light));

    auto center1 = point3(400, 400, 200);
    auto center2 = center1 + vec3(30,0,0);
    auto moving_sphere_material = make_shared<lambertian>(color(0.7, 0.3, 0.1));
    objects.add(make_shared<moving_sphere>(center1, center2, 0, 1, 50, moving_sphere_material));

    objects.add(make_shared<sphere>(point3(260, 150, 45), 50, make_shared<dielectric>(1.5)));
    objects.add(make_shared<sphere>(
        point3(0, 150, 145), 50, make_shared<metal>(color(0.8, 0.8, 0.9), 1.0)
    ));

    auto boundary = make_shared<sphere>(point3(360,150,145), 70, make_shared<dielectric>(1.5));
    objects.add(boundary);
    objects.add(make_shared<constant_medium>(boundary, 0.2, color(0.2, 0.4, 0.9)));
    boundary = make_shared<sphere>(point3(0,0,0), 5000, make_shared<dielectric>(1.5));
    objects.add(make_shared<constant_medium>(boundary, .0001, color(1,1,1)));

    auto emat = make_shared<lambertian>(make_shared<image_texture>(earthmap_path));  // book: "earthmap.jpg"
    objects.add(make_shared<sphere>(point3(400,200,400), 100, emat));
    auto pertext = make_shared<noise_texture>(0.1);
    objects.add(make_shared<sphere>(point3(220,280,300), 80, make_shared<lambertian>(pertext)));

    hittable_list boxes2;
    auto white = make_shared<lambertian>(color(.73, .73, .73));
    int ns = 1000;
    for (int j = 0; j < ns; j++) {
        boxes2.add(make_shared<sphere>(point3::random(0,165), 10, white));
    }

    objects.add(make_shared<translate>(
        make_shared<rotate_y>(
            make_shared<bvh_node>(boxes2, 0.0, 1.0), 15),
            vec3(-100,270,395)
        )
    );

    return objects;
}


//----------------------------------------------------------------------------------------------
// Command line.
//----------------------------------------------------------------------------------------------

static const char* const scene_names[] = {
    "2.01", "2.02", "2.03", "2.07", "2.08", "2.09", "2.10", "2.11", "2.12", "2.13",
    "2.15", "2.16", "2.17", "2.18", "2.19", "2.20", "2.21", "2.22"
};

static void usage_and_exit(const char* message) {
    if (message)
        std::cerr << "reference: " << message << "\n";
    std::cerr << "usage: reference SCENE WIDTH SPP SEED [SCENE_SEED] > out.ppm\n"
              << "  SCENE: one of";
    for (auto name : scene_names)
        std::cerr << ' ' << name;
    std::cerr << "\n  WIDTH: image width in pixels (height = int(WIDTH / aspect_ratio), at least 2)\n"
              << "  SPP:   samples per pixel (at least 1)\n"
              << "  SEED:  passed to srand() before the scene is built; 1 = the book's stream\n"
              << "  SCENE_SEED: if given, srand(SCENE_SEED) builds the scene, srand(SEED) renders\n"
              << "  env EARTHMAP: earth texture for 2.15 and 2.22 (default: earthmap.jpg)\n";
    std::exit(2);
}

static long parse_long(const char* text, const char* what, long min, long max) {
    errno = 0;
    char* end = nullptr;
    long value = std::strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || value < min || value > max) {
        std::string message = std::string("bad ") + what + " '" + text + "'";
        usage_and_exit(message.c_str());
    }
    return value;
}


int main(int argc, char** argv) {
    if (argc != 5 && argc != 6)
        usage_and_exit(argc == 1 ? nullptr : "expected 4 or 5 arguments");

    const std::string scene = argv[1];
    bool known = false;
    for (auto name : scene_names)
        known = known || scene == name;
    if (!known) {
        std::string message = "unknown SCENE '" + scene + "'";
        usage_and_exit(message.c_str());
    }

    const int image_width_arg = static_cast<int>(parse_long(argv[2], "WIDTH", 2, 100000));
    const int samples_per_pixel_arg = static_cast<int>(parse_long(argv[3], "SPP", 1, INT_MAX));
    const unsigned seed = static_cast<unsigned>(parse_long(argv[4], "SEED", 0, UINT_MAX));
    const bool own_scene_seed = argc == 6;
    const unsigned scene_seed =
        own_scene_seed ? static_cast<unsigned>(parse_long(argv[5], "SCENE_SEED", 0, UINT_MAX))
                       : seed;

    const char* earthmap_env = std::getenv("EARTHMAP");
    if (earthmap_env && *earthmap_env)
        earthmap_path = earthmap_env;

    // The book prints an error and renders a cyan sphere when the texture is missing; a
    // reference must not do that silently. stbi_info() makes no random draws.
    if (scene == "2.15" || scene == "2.22") {
        int x, y, comp;
        if (!stbi_info(earthmap_path, &x, &y, &comp)) {
            std::cerr << "reference: cannot read earth texture '" << earthmap_path
                      << "' (set EARTHMAP): " << stbi_failure_reason() << "\n";
            return 1;
        }
    }

    // Image

    auto aspect_ratio = 16.0 / 9.0;
    int image_width = image_width_arg;
    int samples_per_pixel = samples_per_pixel_arg;
    int max_depth = 50;

    // World

    srand(scene_seed);

    hittable_list world;

    point3 lookfrom;
    point3 lookat;
    auto vfov = 40.0;
    auto aperture = 0.0;
    color background(0,0,0);
    bool sky_gradient = false;   // true: book 1's ray_color (figures 2.01-2.15)

    const point3 cornell_lookfrom(278, 278, -800);
    const point3 cornell_lookat(278, 278, 0);

    if (scene == "2.01" || scene == "2.02") {
        world = random_scene_text(scene == "2.02");
        sky_gradient = true;
        lookfrom = point3(13,2,3);
        lookat = point3(0,0,0);
        vfov = 20.0;
        aperture = 0.1;
    } else if (scene == "2.03") {
        world = two_spheres();
        sky_gradient = true;
        lookfrom = point3(13,2,3);
        lookat = point3(0,0,0);
        vfov = 20.0;
    } else if (scene == "2.07" || scene == "2.08" || scene == "2.09" || scene == "2.10" ||
               scene == "2.11" || scene == "2.12" || scene == "2.13") {
        if (scene == "2.07")      world = two_perlin_spheres_with(make_shared<hashed_noise_texture>());
        else if (scene == "2.08") world = two_perlin_spheres_with(make_shared<trilinear_noise_texture>());
        else if (scene == "2.09") world = two_perlin_spheres_with(make_shared<smoothed_noise_texture>(1));
        else if (scene == "2.10") world = two_perlin_spheres_with(make_shared<smoothed_noise_texture>(4));
        else if (scene == "2.11") world = two_perlin_spheres_with(make_shared<shifted_noise_texture>(4));
        else if (scene == "2.12") world = two_perlin_spheres_with(make_shared<turb_noise_texture>(4));
        else                      world = two_perlin_spheres();   // 2.13: the final noise_texture
        sky_gradient = true;
        lookfrom = point3(13,2,3);
        lookat = point3(0,0,0);
        vfov = 20.0;
    } else if (scene == "2.15") {
        world = earth();
        sky_gradient = true;
        lookfrom = point3(13,2,3);   // the text's listing; the final main.cc has (0,0,12)
        lookat = point3(0,0,0);
        vfov = 20.0;
    } else if (scene == "2.16" || scene == "2.17") {
        world = scene == "2.16" ? simple_light_text() : simple_light();
        background = color(0,0,0);
        lookfrom = point3(26,3,6);
        lookat = point3(0,2,0);
        vfov = 20.0;
    } else if (scene == "2.18" || scene == "2.19" || scene == "2.20" || scene == "2.21") {
        if (scene == "2.18")      world = cornell_box_text(false);
        else if (scene == "2.19") world = cornell_box_text(true);
        else if (scene == "2.20") world = cornell_box();
        else                      world = cornell_smoke();
        aspect_ratio = 1.0;
        background = color(0,0,0);
        lookfrom = cornell_lookfrom;
        lookat = cornell_lookat;
        vfov = 40.0;
    } else {   // 2.22
        world = final_scene();
        aspect_ratio = 1.0;
        background = color(0,0,0);
        lookfrom = point3(478, 278, -600);
        lookat = point3(278, 278, 0);
        vfov = 40.0;
    }

    // Camera

    const vec3 vup(0,1,0);
    const auto dist_to_focus = 10.0;
    const int image_height = static_cast<int>(image_width / aspect_ratio);
    if (image_height < 2)
        usage_and_exit("WIDTH too small: the image height must be at least 2");

    camera cam(lookfrom, lookat, vup, vfov, aspect_ratio, aperture, dist_to_focus, 0.0, 1.0);

    // Render

    if (own_scene_seed)
        srand(seed);

    std::cout << "P3\n" << image_width << ' ' << image_height << "\n255\n";

    for (int j = image_height-1; j >= 0; --j) {
        std::cerr << "\rScanlines remaining: " << j << ' ' << std::flush;
        for (int i = 0; i < image_width; ++i) {
            color pixel_color(0,0,0);
            for (int s = 0; s < samples_per_pixel; ++s) {
                auto u = (i + random_double()) / (image_width-1);
                auto v = (j + random_double()) / (image_height-1);
                ray r = cam.get_ray(u, v);
                if (sky_gradient)
                    pixel_color += ray_color_sky(r, world, max_depth);
                else
                    pixel_color += ray_color(r, background, world, max_depth);
            }
            write_color(std::cout, pixel_color, samples_per_pixel);
        }
    }

    std::cerr << "\nDone.\n";
}
