// expect: HashGrid: Levels must be between 1 and 32
#include <evnerf/nn/encoding.hpp>
int main() { return evnerf::nn::HashGrid<0, 2, 14, 16, 512>::out_dims; }
