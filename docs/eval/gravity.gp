# gravity.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot gravity.gp
if (!exists("outfile")) outfile = "gravity.png"
set terminal pngcairo size 900,900 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set multiplot layout 2,1 title "2-D (gravity-aligned) vs 3-D BSF-RANSAC with a perturbed gravity (thesis 4.3)"
set xlabel "gravity error [deg]"
set grid
set key top left
set ylabel "RMSE, eq. 3.6 [mm]"
plot "gravity.csv" skip 1 using 1:(strcol(2) eq "3d" ? $3*1000 : NaN) with linespoints lw 2 title "3-D (no gravity)", "" skip 1 using 1:(strcol(2) eq "2d" ? $3*1000 : NaN) with linespoints lw 2 title "2-D with gravity"
set ylabel "normal error [deg]"
plot "gravity.csv" skip 1 using 1:(strcol(2) eq "3d" ? $4 : NaN) with linespoints lw 2 title "3-D (no gravity)", "" skip 1 using 1:(strcol(2) eq "2d" ? $4 : NaN) with linespoints lw 2 title "2-D with gravity"
unset multiplot
