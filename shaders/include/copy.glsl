// Instances (issue 23; vdmbake.common.instances): a copy's similarity M = [A | c], A = s R, anchor-relative,
// as a per-instance mat4. A ray is taken into the copy's own frame, where the baked data lives:
// M^-1 p = R^T (p - c) / s = A^T (p - c) / s^2. The ray parameter is the same in both frames, so a hit's t
// found there is the world ray's; normals turn back by R = A / s.
void into_copy(mat4 model, inout vec3 p, inout vec3 d) {
    mat3 A = mat3(model);
    float s2 = dot(A[0], A[0]);
    p = transpose(A) * (p - model[3].xyz) / s2;
    d = transpose(A) * d / s2;
}
