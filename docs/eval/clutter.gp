# clutter.png, drawn by `wallar eval`. Redraw from this folder with:
#   gnuplot clutter.gp
if (!exists("outfile")) outfile = "clutter.png"
set terminal pngcairo size 900,650 font "DejaVu Sans,11" noenhanced
set output outfile
set datafile separator ","
set datafile missing NaN
set title "Clutter: boxes between the front plane and the wall (rho_b 0.3)\n(normal within 5 deg and offset within 0.1 m of the true wall)"
set xlabel "points on the boxes"
set ylabel "robustness (eq. 3.7)"
set yrange [-0.05:1.05]
set grid
set key outside right
plot "clutter.csv" skip 1 using 1:(strcol(2) eq "ransac" ? $5 : NaN) with linespoints lw 2 title "ransac", "" skip 1 using 1:(strcol(2) eq "bsf" ? $5 : NaN) with linespoints lw 2 title "bsf", "" skip 1 using 1:(strcol(2) eq "binomial" ? $5 : NaN) with linespoints lw 2 title "binomial"
