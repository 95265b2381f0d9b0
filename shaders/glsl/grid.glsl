// The cloth's unit normal at a vertex from its grid neighbours, read by position_in(index) (so
// each kernel includes this after defining it): (x[i+1,j] − x[i−1,j]) × (x[i,j+1] − x[i,j−1]),
// one-sided at the edges (cloth_core::forces::grid_normal).
vec3 grid_normal(uint index) {
    uint nx = params.grid_nx;
    uint i = index % nx;
    uint j = index / nx;
    uint left = i > 0u ? i - 1u : i;
    uint right = i + 1u < nx ? i + 1u : i;
    uint down = j > 0u ? j - 1u : j;
    uint up = j + 1u < params.grid_ny ? j + 1u : j;
    vec3 along_u = position_in(j * nx + right) - position_in(j * nx + left);
    vec3 along_v = position_in(up * nx + i) - position_in(down * nx + i);
    vec3 n = cross(along_u, along_v);
    float len = sqrt(dot(n, n));
    if (len > 0.0) {
        return n * (1.0 / len);
    }
    return vec3(0.0);
}
