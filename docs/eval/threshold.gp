# threshold.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot threshold.gp
if (!exists("outfile")) outfile = "threshold.png"
set terminal pngcairo size 900,900 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set multiplot layout 2,1 title "Threshold vs accuracy (fig. 4.4); wall noise 0.1 m (uniform, full width)"
set logscale x
set xlabel "inlier threshold [m]"
set key top left
set grid
set ylabel "RMSE, eq. 3.6 [mm]"
plot "threshold.csv" skip 1 using 1:(strcol(2) eq "ransac" ? $3*1000 : NaN) with linespoints title "RANSAC", "" skip 1 using 1:(strcol(2) eq "bsf" ? $3*1000 : NaN) with linespoints title "BSF-RANSAC"
set ylabel "inliers"
plot "threshold.csv" skip 1 using 1:(strcol(2) eq "ransac" ? $4 : NaN) with linespoints title "RANSAC", "" skip 1 using 1:(strcol(2) eq "bsf" ? $4 : NaN) with linespoints title "BSF-RANSAC"
unset multiplot
