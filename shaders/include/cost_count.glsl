// Device-independent cost counters, read by vdmrender/measuring/counters.py. A fragment stage compiled with COUNT
// (counters.counting: gl.program defines it for the fragment stage) adds, by atomics, to four counters in
// one shader storage buffer at binding 7 (each 64 bits, below):
//   [0] fragments  COUNT_FRAGMENT(), first in every fragment stage's main: each rasterised fragment that runs
//                  the stage. A stage that writes a storage buffer has its depth test after it (only
//                  layout(early_fragment_tests) moves it before), so this is the overdraw the rasteriser
//                  hands the stage, whatever a device's early depth test would have saved;
//   [1] fetches    FETCH(e) around every texture read (texture, textureLod, textureGrad, texelFetch,
//                  textureGather: one each; textureSize reads no texel and is not one);
//   [2] steps      STEP() once per iteration of every search, march or trace loop (what each stage counts
//                  is said where it counts);
//   [3] searches   SEARCH() once per ray searched through a height field, depth map or table: a view or
//                  shadow ray of pom, relief or vdm (a VDM lookup stands for its ray), each billboard box
//                  marched or billboard traced, each octahedral view searched; so steps / searches is a
//                  search's mean length.
// Helper invocations (run for derivatives) have their stores discarded by GL, so the counts are exact. The
// instrumented build draws the same picture: the macros only add the atomics. Without COUNT they are the
// expression itself or nothing, and the normal build is what it was.
// Each counter is 64 bits made of two 32-bit words (atomics on 64-bit integers are an extension llvmpipe lacks):
// the add that wraps the low word (it returns 0xFFFFFFFF) carries one into the high word, so the counts are exact
// past 2^32 (a supersampled 4K frame's fetches reach it; vdmrender/measuring/counters.py joins the words).
#ifdef COUNT
layout(std430, binding = 7) buffer CostCounts {
    uint cost_counts[8];   // low words [0..3], high words [4..7]
};
uint count_one(int i) {
    if (atomicAdd(cost_counts[i], 1u) == 0xFFFFFFFFu)
        atomicAdd(cost_counts[4 + i], 1u);
    return 0u;
}
#define COUNT_FRAGMENT() count_one(0)
#define FETCH(e) (count_one(1), (e))
#define STEP() count_one(2)
#define SEARCH() count_one(3)
#else
#define COUNT_FRAGMENT()
#define FETCH(e) (e)
#define STEP()
#define SEARCH()
#endif
