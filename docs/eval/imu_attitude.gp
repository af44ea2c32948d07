# imu_attitude.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot imu_attitude.gp
if (!exists("outfile")) outfile = "imu_attitude.png"
set terminal pngcairo size 900,700 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set multiplot layout 2,1 title "Attitude filter on EuRoC V1_01: errors against ground truth"
set grid
set key top right
set xlabel "time [s]"
set ylabel "tilt error [deg]"
plot "imu_attitude.csv" skip 1 using 1:2 with lines lw 1.5 title "tilt (roll+pitch) error"
set ylabel "gyro bias error [mrad/s]"
plot "imu_attitude.csv" skip 1 using 1:3 with lines title "x", "" skip 1 using 1:4 with lines title "y", "" skip 1 using 1:5 with lines title "z", "" skip 1 using 1:6 with lines lw 2 title "norm"
unset multiplot
