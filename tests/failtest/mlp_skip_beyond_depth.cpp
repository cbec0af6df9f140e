// expect: the skip connection must feed a hidden layer
#include <evnerf/nn/mlp.hpp>
int main() { return static_cast<int>(evnerf::nn::Mlp<63, 256, 4, 1, evnerf::nn::ReLU, evnerf::nn::Identity, 4>::n_params); }
