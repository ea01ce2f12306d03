// Texture fetches counted per fragment, for profiles. Built with COUNT defined, a fragment stage
// wraps each fetch in FETCH(kind, ...) and writes `fetches` instead of its colour (COUNT_OUT);
// otherwise FETCH is the fetch itself. Kinds: 0 table weights (VDM's W), 1 eigenfunction tables
// (E_vdm, E_mvm), 2 height field, 3 the rest (normals, shadow map, albedo tile).
#ifdef COUNT
ivec4 fetches = ivec4(0);
#define FETCH(kind, e) (fetches[kind] += 1, (e))
#define COUNT_OUT(frag) frag = vec4(fetches)
#else
#define FETCH(kind, e) (e)
#define COUNT_OUT(frag)
#endif
