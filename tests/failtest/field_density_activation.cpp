// expect: DensityNet must end in nn::Identity
#include <evnerf/field/field.hpp>
using namespace evnerf;
using F = field::Field<nn::Frequency<2>, nn::Frequency<1>, nn::Mlp<15, 16, 1, 5, nn::ReLU, nn::ReLU>,
                       nn::Mlp<4 + 9, 16, 1, 1, nn::ReLU, nn::Identity>>;
int main() { return static_cast<int>(F::n_params); }
