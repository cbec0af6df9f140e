# Sourced by the speed scripts: the CPU's vector features, as /proc/cpuinfo names them (`has FLAG`), and
# CPU_FEATURES, the short form the results page names beside each figure.
cpu_flags=" $(grep -m1 '^flags' /proc/cpuinfo | cut -d: -f2) "
has() { [[ $cpu_flags == *" $1 "* ]]; }
CPU_FEATURES="$(has avx512f && echo AVX-512 || echo "no AVX-512")$(has avx2 && echo ", AVX2")$(has fma && echo " + FMA")"
