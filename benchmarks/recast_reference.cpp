// Reference walkable area from Recast (C++), for comparison with baker.navmesh.
//
// Build (Debian: apt-get install librecast-dev):
//   g++ -O2 -o /tmp/recast_reference benchmarks/recast_reference.cpp -I/usr/include/recastnavigation -lRecast
// Run:
//   /tmp/recast_reference MESH.obj CELL_SIZE CELL_HEIGHT RADIUS HEIGHT CLIMB SLOPE_DEG [MIN_REGION_CELLS]
//
// Follows RecastDemo's Sample_SoloMesh up to the regions: rasterize, filter low hanging
// obstacles / ledges / low height spans, compact, erode by the radius, distance field,
// regions (islands smaller than MIN_REGION_CELLS, default 8 x 8, are dropped). Prints the
// walkable area (cs^2 per span with a region), the span count, the build time and the build's
// memory: the peak resident memory during the build (Linux VmHWM, reset through
// /proc/self/clear_refs once the mesh is loaded) above the resident memory before it.
#include <Recast.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

// VmRSS or VmHWM of this process in kB (Linux; 0 elsewhere).
static long procStatusKb(const char* key) {
    std::ifstream in("/proc/self/status");
    std::string line;
    const size_t n = std::strlen(key);
    while (std::getline(in, line))
        if (line.compare(0, n, key) == 0) return std::atol(line.c_str() + n + 1);
    return 0;
}

static bool loadObj(const char* path, std::vector<float>& verts, std::vector<int>& tris) {
    std::ifstream in(path);
    if (!in) return false;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream ss(line);
        std::string tag;
        ss >> tag;
        if (tag == "v") {
            float x, y, z;
            ss >> x >> y >> z;
            verts.push_back(x); verts.push_back(y); verts.push_back(z);
        } else if (tag == "f") {
            std::vector<int> idx;
            std::string tok;
            while (ss >> tok) {
                int i = std::atoi(tok.c_str());
                if (i < 0) i = (int)(verts.size() / 3) + i + 1;
                idx.push_back(i - 1);
            }
            for (size_t k = 2; k < idx.size(); ++k) {
                tris.push_back(idx[0]); tris.push_back(idx[k - 1]); tris.push_back(idx[k]);
            }
        }
    }
    return true;
}

int main(int argc, char** argv) {
    if (argc < 8) {
        std::fprintf(stderr, "usage: %s MESH.obj CS CH RADIUS HEIGHT CLIMB SLOPE_DEG [MIN_REGION_CELLS]\n", argv[0]);
        return 2;
    }
    std::vector<float> verts;
    std::vector<int> tris;
    if (!loadObj(argv[1], verts, tris)) { std::fprintf(stderr, "cannot read %s\n", argv[1]); return 1; }
    const float cs = std::atof(argv[2]), ch = std::atof(argv[3]);
    const float radius = std::atof(argv[4]), height = std::atof(argv[5]);
    const float climb = std::atof(argv[6]), slope = std::atof(argv[7]);
    const int minRegion = argc > 8 ? std::atoi(argv[8]) : 64;
    const int nv = (int)verts.size() / 3, nt = (int)tris.size() / 3;

    { std::ofstream reset("/proc/self/clear_refs"); reset << "5"; }  // peak := current
    const long rssBefore = procStatusKb("VmRSS:");
    const std::clock_t c0 = std::clock();
    auto t0 = std::chrono::steady_clock::now();
    rcContext ctx(false);
    rcConfig cfg{};
    cfg.cs = cs; cfg.ch = ch;
    cfg.walkableSlopeAngle = slope;
    cfg.walkableHeight = (int)std::ceil(height / ch);
    cfg.walkableClimb = (int)std::floor(climb / ch);
    cfg.walkableRadius = (int)std::ceil(radius / cs);
    cfg.minRegionArea = minRegion;
    cfg.mergeRegionArea = 20 * 20;
    rcCalcBounds(verts.data(), nv, cfg.bmin, cfg.bmax);
    rcCalcGridSize(cfg.bmin, cfg.bmax, cfg.cs, &cfg.width, &cfg.height);

    rcHeightfield* hf = rcAllocHeightfield();
    rcCreateHeightfield(&ctx, *hf, cfg.width, cfg.height, cfg.bmin, cfg.bmax, cfg.cs, cfg.ch);
    std::vector<unsigned char> areas(nt, 0);
    rcMarkWalkableTriangles(&ctx, cfg.walkableSlopeAngle, verts.data(), nv, tris.data(), nt, areas.data());
    rcRasterizeTriangles(&ctx, verts.data(), nv, tris.data(), areas.data(), nt, *hf, cfg.walkableClimb);
    rcFilterLowHangingWalkableObstacles(&ctx, cfg.walkableClimb, *hf);
    rcFilterLedgeSpans(&ctx, cfg.walkableHeight, cfg.walkableClimb, *hf);
    rcFilterWalkableLowHeightSpans(&ctx, cfg.walkableHeight, *hf);
    rcCompactHeightfield* chf = rcAllocCompactHeightfield();
    rcBuildCompactHeightfield(&ctx, cfg.walkableHeight, cfg.walkableClimb, *hf, *chf);
    rcErodeWalkableArea(&ctx, cfg.walkableRadius, *chf);
    long eroded = 0;
    for (int i = 0; i < chf->spanCount; ++i) eroded += chf->areas[i] != RC_NULL_AREA;
    rcBuildDistanceField(&ctx, *chf);
    rcBuildRegions(&ctx, *chf, 0, cfg.minRegionArea, cfg.mergeRegionArea);
    long spans = 0;
    for (int i = 0; i < chf->spanCount; ++i)
        spans += chf->areas[i] != RC_NULL_AREA && chf->spans[i].reg != 0;
    double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
    const long peak = procStatusKb("VmHWM:");
    std::printf("grid %d x %d, eroded walkable spans %ld (%.2f m^2), in regions %ld, walkable area %.2f m^2, build %.3f s (cpu %.3f s), build memory %.1f MB (peak %.1f MB, before %.1f MB)\n",
                cfg.width, cfg.height, eroded, eroded * cs * cs, spans, spans * cs * cs, sec, cpu,
                (peak - rssBefore) / 1024.0, peak / 1024.0, rssBefore / 1024.0);
    return 0;
}
