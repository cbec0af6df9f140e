// expect: HiddenAct must be an activation type
#include <evnerf/nn/mlp.hpp>
struct NotAnActivation {};
int main() { return static_cast<int>(evnerf::nn::Mlp<3, 16, 2, 1, NotAnActivation>::n_params); }
