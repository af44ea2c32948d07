# marker_accuracy.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot marker_accuracy.gp
if (!exists("outfile")) outfile = "marker_accuracy.png"
set terminal pngcairo size 1300,560 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
# Marker ground truth: plane error of the ArUco estimate against the rendered truth.
# Medians over 5 renders per point (marker_accuracy.csv has each).
set multiplot layout 1,2 title "ArUco 4X4_50, 177 mm marker, cam0 752x480, noise sigma 2"
set key top left
set grid
set logscale y
set xrange [0.3:3.1]
set xlabel "distance [m]"
set ylabel "normal error [deg]"
plot for [i=0:4] 'marker_accuracy_medians.csv' using 1:(column(2+i)) with linespoints title sprintf('%d deg', int(word('0 15 30 45 60', i+1))), 0.5 with lines dashtype 2 lc rgb 'black' title 'thesis ARToolKit (<=1 m, <=45 deg)'
set ylabel "offset error [mm]"
plot for [i=0:4] 'marker_accuracy_medians.csv' using 1:(column(7+i)) with linespoints title sprintf('%d deg', int(word('0 15 30 45 60', i+1))), 3.0 with lines dashtype 2 lc rgb 'black' title 'thesis ARToolKit (<=1 m, <=45 deg)'
unset multiplot
